"""SIGTERM is handled like Ctrl-C: temporaries removed, exit 143, the previous output intact.

In-process tests stop ``render`` and ``report`` at chosen points by sending SIGTERM to the test
process itself from inside the pipeline (the handler raises at once); one slow test kills the
real command at a few moments from outside.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import starsense._io.files as files
import starsense.render.io as rio
import starsense.render.scene as scene
import starsense.render.sequence as sequence  # bound before a test patches scene.render_frame
import starsense.report.build as build
from starsense._io import atomic_write, sweep_stale
from starsense.cli import main
from starsense.cli.app import EXIT_TERMINATED
from starsense.sensor import load_sensor


def _term(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGTERM)
    raise AssertionError("SIGTERM did not interrupt")  # pragma: no cover


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture
def old_frame(tmp_path: Path) -> Path:
    (tmp_path / "f.png").write_bytes(b"old image")
    (tmp_path / "f.png.json").write_text('{"old": true}')
    return tmp_path / "f.png"


def _assert_old_frame(frame: Path, code: int, err: str) -> None:
    assert code == EXIT_TERMINATED == 143
    assert err.strip() == "error: terminated (SIGTERM); nothing written"
    assert frame.read_bytes() == b"old image"
    assert frame.with_name("f.png.json").read_text() == '{"old": true}'
    assert _files(frame.parent) == ["f.png", "f.png.json"]  # no temporary left


def test_render_terminated_while_rendering(old_frame, monkeypatch, capsys):
    monkeypatch.setattr(scene, "render_frame", _term)
    code = main(["render", "--out", str(old_frame)])
    _assert_old_frame(old_frame, code, capsys.readouterr().err)


def test_render_terminated_while_writing_the_image(old_frame, monkeypatch, capsys):
    def half_written(target, image, fmt, when=None):
        Path(target).write_bytes(b"half an image")
        _term()

    monkeypatch.setattr(rio, "_write_pillow", half_written)
    code = main(["render", "--out", str(old_frame), "--max-mag", "3"])
    _assert_old_frame(old_frame, code, capsys.readouterr().err)


def test_render_terminated_during_the_commit_finishes_it(old_frame, monkeypatch, capsys):
    # SIGTERM while the image and its truth are renamed into place is held back until both
    # are: the new pair is complete (never a new image with the old truth), then exit 143

    real = files._fsync
    sent = []

    def fsync_then_term(path):
        real(path)
        if not sent and Path(path).parent == old_frame.parent:  # not a catalogue cache write
            sent.append(path)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(files, "_fsync", fsync_then_term)
    code = main(["render", "--out", str(old_frame), "--max-mag", "3"])
    assert code == 143 and sent
    # the one line says so: the signal came, and the files written before it are complete
    err = capsys.readouterr().err.strip()
    said = f"error: terminated (SIGTERM); written before it, complete: {old_frame} and 1 more"
    assert err == said
    from PIL import Image

    det = load_sensor("st16").detector
    with Image.open(old_frame) as im:  # the new frame, complete: the st16 detector's size
        assert im.size == (det.columns, det.rows)
    assert "stars" in json.loads(old_frame.with_name("f.png.json").read_text())
    assert _files(old_frame.parent) == ["f.png", "f.png.json"]


@pytest.fixture
def old_report(tmp_path: Path) -> Path:
    out = tmp_path / "r"
    out.mkdir()
    (out / "report.json").write_text(json.dumps({"generator": "starsense.report"}))
    (out / "index.html").write_text("old report")
    return out


def _assert_old_report(out: Path, code: int, err: str) -> None:
    assert code == 143 and "terminated" in err
    assert (out / "index.html").read_text() == "old report"
    assert _files(out) == ["index.html", "report.json"]
    assert _files(out.parent) == ["r"]  # no temporary or set-aside folder left


def test_report_terminated_while_loading_stars(old_report, monkeypatch, capsys):
    monkeypatch.setattr(build, "_load_stars", _term)
    code = main(["report", "--out", str(old_report)])
    _assert_old_report(old_report, code, capsys.readouterr().err)


def _fake_stars(monkeypatch):
    monkeypatch.setattr(build, "_load_stars", lambda *a: ("test stars", 1, {}, None))
    return build


def test_report_terminated_in_a_section(old_report, monkeypatch, capsys):
    build = _fake_stars(monkeypatch)
    monkeypatch.setattr(build, "SECTION_BUILDERS", [_term])
    code = main(["report", "--out", str(old_report)])
    _assert_old_report(old_report, code, capsys.readouterr().err)


def test_report_terminated_while_writing(old_report, monkeypatch, capsys):
    build = _fake_stars(monkeypatch)
    monkeypatch.setattr(build, "SECTION_BUILDERS", [])

    def half_index(work, *args):
        (work / "index.html").write_text("half")
        _term()

    monkeypatch.setattr(build, "_write_index", half_index)
    code = main(["report", "--out", str(old_report)])
    _assert_old_report(old_report, code, capsys.readouterr().err)


def test_report_terminated_during_the_swap_finishes_it(old_report, monkeypatch, capsys):
    build = _fake_stars(monkeypatch)
    monkeypatch.setattr(build, "SECTION_BUILDERS", [])
    monkeypatch.setattr(
        build, "_write_index", lambda work, *a: (work / "index.html").write_text("new")
    )
    monkeypatch.setattr(
        build,
        "_write_json",
        lambda work, *a: (work / "report.json").write_text(
            json.dumps({"generator": "starsense.report"})
        ),
    )
    real = build._swap_into_place

    def swap_after_term(work, out):
        os.kill(os.getpid(), signal.SIGTERM)  # held back until the swap is done
        real(work, out)

    monkeypatch.setattr(build, "_swap_into_place", swap_after_term)
    code = main(["report", "--out", str(old_report)])
    assert code == 143
    assert (old_report / "index.html").read_text() == "new"
    assert _files(old_report.parent) == ["r"]


def test_stale_temporaries_of_a_killed_run_are_swept(tmp_path, monkeypatch, capsys):
    # a run killed outright (SIGKILL) leaves its temporaries; the next run into the same place
    # removes those of dead processes and leaves a live process's alone
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = os.getpid()
    stale_file = tmp_path / f".f.png.starsense-{dead.pid}-abc123.png"
    stale_dir = tmp_path / f".r.starsense-{dead.pid}-tmp-xyz"
    busy = tmp_path / f".f.png.starsense-{live}-inuse.png"
    stale_file.write_bytes(b"x")
    stale_dir.mkdir()
    (stale_dir / "index.html").write_text("x")
    busy.write_bytes(b"x")

    with atomic_write(tmp_path / "f.png", "wb") as fh:
        fh.write(b"new")
    assert not stale_file.exists() and busy.exists()
    assert sweep_stale(tmp_path / "r") == [stale_dir]
    assert _files(tmp_path) == sorted(["f.png", busy.name])


@pytest.mark.slow
def test_render_killed_from_outside_at_several_moments(tmp_path):
    # the real command, SIGTERM at a few moments of its run (start-up, rendering, writing):
    # each time exit 143 (or 0 when it had finished, or -15 before the handler was set), no
    # temporary, and either the previous frame or a complete new one
    frame = tmp_path / "f.png"
    cmd = [
        sys.executable,
        "-c",
        "from starsense.cli import console_main; console_main()",
        "render",
        "--out",
        str(frame),
        "--max-mag",
        "4",
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    previous = (frame.read_bytes(), frame.with_name("f.png.json").read_bytes())
    for delay in (0.5, 1.5, 2.5, 3.5):
        proc = subprocess.Popen(
            [*cmd, "--seed", "7"], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode in (143, 0, -signal.SIGTERM), err
        assert b"Traceback" not in err
        assert _files(tmp_path) == ["f.png", "f.png.json"]
        now = (frame.read_bytes(), frame.with_name("f.png.json").read_bytes())
        if now != previous:  # replaced: the new pair is complete
            assert "stars" in json.loads(now[1])
            previous = now


# -- render --sequence: the sequence is one unit ---------------------------------------------

SEQ_N = 20


@pytest.fixture
def old_sequence(tmp_path: Path) -> Path:
    """A previous 20-frame sequence s_000.png ... s_019.png with its truths."""
    for k in range(SEQ_N):
        (tmp_path / f"s_{k:03d}.png").write_bytes(f"old image {k}".encode())
        (tmp_path / f"s_{k:03d}.png.json").write_text(f'{{"old": {k}}}')
    return tmp_path


def _assert_old_sequence(folder: Path, code: int, err: str) -> None:
    assert code == EXIT_TERMINATED == 143
    assert err.strip() == "error: terminated (SIGTERM); nothing written"
    names = [f"s_{k:03d}.png{ext}" for k in range(SEQ_N) for ext in ("", ".json")]
    assert _files(folder) == sorted(names)  # no new frame, no temporary
    for k in range(SEQ_N):
        assert (folder / f"s_{k:03d}.png").read_bytes() == f"old image {k}".encode()
        assert (folder / f"s_{k:03d}.png.json").read_text() == f'{{"old": {k}}}'


def _sequence_argv(folder: Path) -> list[str]:
    return [
        "render", "--out", str(folder / "s.png"), "--sequence", str(SEQ_N),
        "--interval-s", "0.2", "--max-mag", "3", "--no-noise",
    ]  # fmt: skip


def _term_on_call(n: int, real):
    """A stand-in for ``real`` that sends SIGTERM on its ``n``-th call (1-based)."""
    calls = []

    def wrapped(*args, **kwargs):
        calls.append(1)
        if len(calls) == n:
            _term()
        return real(*args, **kwargs)

    return wrapped


@pytest.mark.parametrize(
    ("where", "call"),
    [("render", 1), ("render", 11), ("write", SEQ_N)],
    ids=["rendering the first frame", "rendering frame 10", "writing the last frame"],
)
def test_render_sequence_terminated_leaves_the_old_sequence(
    old_sequence, monkeypatch, capsys, where, call
):
    # SIGTERM at three moments of `render --sequence 20`: before any frame, half-way, and
    # with every frame but the last written to its temporary: nothing of the new sequence
    # stays, the old one is intact, exit 143
    if where == "render":
        monkeypatch.setattr(sequence, "render_frame", _term_on_call(call, sequence.render_frame))
    else:
        monkeypatch.setattr(rio, "_write_pillow", _term_on_call(call, rio._write_pillow))
    code = main(_sequence_argv(old_sequence))
    _assert_old_sequence(old_sequence, code, capsys.readouterr().err)


def test_render_sequence_failing_at_a_frame_leaves_the_old_sequence(
    old_sequence, monkeypatch, capsys
):
    real = sequence.render_frame
    calls = []

    def fails_at_frame_5(*args, **kwargs):
        calls.append(1)
        if len(calls) == 6:
            raise OSError(28, "No space left on device")
        return real(*args, **kwargs)

    monkeypatch.setattr(sequence, "render_frame", fails_at_frame_5)
    code = main(_sequence_argv(old_sequence))
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.endswith("s_000.png: No space left on device"), err
    names = [f"s_{k:03d}.png{ext}" for k in range(SEQ_N) for ext in ("", ".json")]
    assert _files(old_sequence) == sorted(names)
    assert (old_sequence / "s_005.png").read_bytes() == b"old image 5"


def test_render_sequence_terminated_during_the_commit_finishes_it(
    old_sequence, monkeypatch, capsys
):
    # SIGTERM while the 40 files are renamed into place is held back until all are: the new
    # sequence is complete (every frame a 16-bit PNG with its truth at its own time), exit 143
    real = files._fsync
    sent = []

    def fsync_then_term(path):
        real(path)
        if not sent and Path(path).parent == old_sequence:  # not a catalogue cache write
            sent.append(path)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(files, "_fsync", fsync_then_term)
    code = main(_sequence_argv(old_sequence))
    assert code == 143 and sent
    from PIL import Image

    det = load_sensor("st16").detector
    for k in range(SEQ_N):
        with Image.open(old_sequence / f"s_{k:03d}.png") as im:
            assert im.size == (det.columns, det.rows)
        truth = json.loads((old_sequence / f"s_{k:03d}.png.json").read_text())
        assert truth["time_s"] == pytest.approx(0.2 * k)
    assert len(_files(old_sequence)) == 2 * SEQ_N


@pytest.mark.slow
def test_render_sequence_killed_from_outside_at_three_moments(old_sequence):
    # the real command: SIGTERM 1, 4 and 8 s after the start (start-up, rendering, writing):
    # exit 143 (or 0 when it had finished, -15 before the handler was set), no temporary,
    # and the sequence is either the old one or a complete new one
    cmd = [sys.executable, "-c", "from starsense.cli import console_main; console_main()"]
    codes = []
    for delay in (1.0, 4.0, 8.0):
        proc = subprocess.Popen(
            [*cmd, *_sequence_argv(old_sequence)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=300)
        codes.append(proc.returncode)
        assert proc.returncode in (143, 0, -signal.SIGTERM), err
        assert b"Traceback" not in err
        assert len(_files(old_sequence)) == 2 * SEQ_N  # no temporary, no extra frame
        truths = [(old_sequence / f"s_{k:03d}.png.json").read_text() for k in range(SEQ_N)]
        old = ['"old"' in t for t in truths]
        assert all(old) or not any(old)  # never a mix of the two sequences
        if proc.returncode == 143:
            assert all(old)  # terminated before its commit: the old sequence stands
            _assert_old_sequence(old_sequence, 143, err.decode())
    assert 143 in codes, codes  # at least one moment fell inside the run
