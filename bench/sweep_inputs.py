"""The inputs of the bad-input sweep (bench/bad_input_sweep.py): the valid files every case
starts from, and the special files and bad inputs a case makes in its own folder.

Special files are made in the case's folder only (a FIFO, a character device with the null
device's numbers, a symbolic link to a FIFO, a bound UNIX socket), never the system's ``/dev``.
"""

from __future__ import annotations

import io
import os
import random
import socket
import stat
import zlib
from pathlib import Path


class Fixtures:
    """The valid inputs every case starts from, built once in ``folder``."""

    def __init__(self, folder: Path) -> None:
        from starsense.cli import main

        self.folder = folder
        self.frame = folder / "frame.png"
        if main(["render", "--out", str(self.frame), "--seed", "1"]) != 0:
            raise RuntimeError("the sweep's frame did not render")
        rng = random.Random(50)
        rows = [
            f"{rng.uniform(0, 360):.5f},{rng.uniform(-89, 89):.5f},{rng.uniform(0, 9):.2f}"
            for _ in range(300)
        ]
        self.csv = folder / "stars.csv"
        self.csv.write_text("ra,dec,V\n" + "\n".join(rows) + "\n")
        from importlib.resources import files

        self.toml = folder / "sensor.toml"
        self.toml.write_text((files("starsense.sensor") / "presets" / "st16.toml").read_text())
        self.tle = folder / "iss.tle"
        self.tle.write_text(
            "ISS (ZARYA)\n"
            "1 25544U 98067A   08264.51782528 -.00002182  00000-0 -11606-4 0  2927\n"
            "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537\n"
        )

    def valid_bytes(self, suffix: str) -> bytes:
        """A valid file of the kind an input of this ending takes."""
        return {".png": self.frame, ".toml": self.toml, ".csv": self.csv, ".txt": self.tle}.get(
            suffix, self.toml
        ).read_bytes()


def _png_claiming(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return len(data).to_bytes(4, "big") + kind + data + crc.to_bytes(4, "big")

    ihdr = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 0, 0, 0, 0])
    idat = zlib.compress(b"\x00" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def _strip_png() -> bytes:
    import numpy as np
    from PIL import Image

    buf = io.BytesIO()
    noise = np.random.default_rng(50).integers(0, 200, (1, 100_000)).astype(np.uint8)
    Image.fromarray(noise).save(buf, format="PNG")
    return buf.getvalue()


def make(path: Path, kind: str, fixtures: Fixtures, rng: random.Random, held: list) -> None:
    """Make what ``kind`` says at ``path`` (a special output, or a bad input ``in:...``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "chardev":  # the null device's numbers, in the case's folder
        os.mknod(path, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    elif kind == "link-to-fifo":
        os.mkfifo(path.parent / ".the-fifo")
        os.symlink(".the-fifo", path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.bind(str(path))
        held.append(s)
    elif kind == "folder":
        path.mkdir()
    elif kind == "file":
        path.write_text("an earlier file\n")
    elif kind.startswith("in:"):
        _make_input(path, kind[3:], fixtures, rng)
    else:
        raise ValueError(kind)


def _make_input(path: Path, bad: str, fixtures: Fixtures, rng: random.Random) -> None:
    valid = fixtures.valid_bytes(path.suffix)
    if bad == "missing":
        return
    if bad == "folder":
        path.mkdir()
    elif bad == "empty":
        path.write_bytes(b"")
    elif bad == "garbage":
        path.write_bytes(rng.randbytes(4096))
    elif bad == "utf16":
        path.write_bytes(valid.decode("latin-1").encode("utf-16"))
    elif bad == "fifo":
        os.mkfifo(path)
    elif bad == "huge-png":
        path.write_bytes(_png_claiming(65535, 65535))
    elif bad == "cut":
        path.write_bytes(valid[: rng.randrange(1, max(2, len(valid) // 2))])
    elif bad == "changed":
        data = bytearray(valid)
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        path.write_bytes(bytes(data))
    elif bad == "strip":
        path.write_bytes(_strip_png())
    else:
        raise ValueError(bad)
