"""The cases of the bad-input and fault sweep (bench/bad_input_sweep.py), drawn from a seed.

Every command of the CLI (read from the app itself, so a new command or option is swept without
editing this file) gets cases of six kinds:

``value``
    one option given a value no option of its type accepts (NaN, infinities, 1e308, a word for a
    number, an empty string, a count of 10**12, a malformed vector, a string of 5,000 characters,
    a NUL byte ...); must be refused.
``output``
    an output path that is a FIFO, a character device (made here, with the null device's
    numbers), a symbolic link to a FIFO, a socket, a folder where a file goes (or a file where
    a folder goes), or in a folder that does not exist; must be refused, the special file left
    as it was.
``input``
    an input file that is missing, a folder, empty, binary garbage, UTF-16 text, a FIFO nobody
    writes, a PNG claiming 65535 x 65535 pixels, a valid file cut short or with bytes changed;
    must be refused, or (a changed file may still be valid) read without a traceback.
``usage``
    a required argument dropped, an unknown option added; must be refused.
``signal``
    a valid, light run of the command sent SIGINT or SIGTERM at a random moment of its first
    three seconds; must end 130 / 143 with nothing written (or finish cleanly before it).
``huge``
    a count option at 10**12, a frame of 1 x 100,000 pixels: refused or answered in bounded memory.

Placeholders in an argument: ``{d}`` the case's own folder, ``{frame}`` / ``{csv}`` / ``{toml}`` /
``{tle}`` the valid inputs built once (``Fixtures``), ``{port}`` a free port.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

#: a light valid run of each command (the base every case changes one thing of)
BASE: dict[str, list[str]] = {
    "render": ["render", "--out", "{d}/f.png", "--no-noise"],
    "solve": ["solve", "{frame}"],
    "calibrate": ["calibrate", "{frame}", "--out", "{d}/cal.toml"],
    "characterize": ["characterize", "{frame}", "--out", "{d}/ch.toml"],
    "montecarlo": ["montecarlo", "--trials", "2"],
    "datasheet": ["datasheet", "--trials", "2", "--n-orientations", "50", "--out", "{d}/ds"],
    "ecss": ["ecss", "--n-orientations", "50", "--n-slew-trials", "2", "--out", "{d}/s.json"],
    "trade": ["trade", "--vary", "exposure_s=0.1,0.2", "--frames", "2", "--out", "{d}/tr"],
    "design": ["design", "--no-open", "--port", "{port}", "--n-orientations", "50"],
    "track": ["track", "{frame}", "{frame}", "--sensor", "st16", "--interval-s", "1"],
    "report": ["report", "--out", "{d}/r", "--trials", "2", "--slew-trials", "2"],
    "limit star": ["limit", "star", "--mag-v", "5", "--b-v", "0.5"],
    "limit sky": ["limit", "sky", "--max-mag", "4"],
    "limit curve": ["limit", "curve", "--plot", "{d}/c.png"],
    "limit photons": ["limit", "photons", "--trials", "10"],
    "slew tolerance": ["slew", "tolerance", "--trials", "4", "--magnitudes", "3,5",
                       "--rates-deg-s", "0,1", "--plot", "{d}/t.png"],
    "slew intensity": ["slew", "intensity", "--trials", "4", "--magnitudes", "3,5",
                       "--rates-deg-s", "0,1"],
    "slew study": ["slew", "study", "--trials", "4"],
    "availability static": ["availability", "static", "--n-orientations", "100",
                            "--plot", "{d}/a.png"],
    "availability dynamic": ["availability", "dynamic", "--n-orientations", "100", "--trials",
                             "4", "--rates-deg-s", "0,1"],
    "availability track": ["availability", "track", "--track-samples", "20", "--trials", "4",
                           "--inclination-step-deg", "45"],
    "availability fidelity": ["availability", "fidelity", "--frames", "2", "--trials", "4"],
    "availability mission": ["availability", "mission", "--heads", "st16", "--tle", "{tle}",
                             "--duration-h", "0.2", "--trials", "4", "--plot", "{d}/m.png"],
    "guide-stars simulate": ["guide-stars", "simulate", "--trials", "20"],
    "guide-stars select": ["guide-stars", "select", "--sensor", "lin2024", "--center-deg",
                           "84,-1"],
    "guide-stars field": ["guide-stars", "field", "--trials", "20"],
    "catalog import": ["catalog", "import", "{csv}", "{d}/hats", "--dask", "local:1"],
}  # fmt: skip

#: values no option of the type accepts (no NUL byte: a command line cannot hold one)
BAD_FLOAT = ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e400", "abc", "", " ", "1,2",
             "0x1p3", "--", "1e30000000"]  # fmt: skip
BAD_INT = ["-1", "abc", "", "1.5", "nan", "99999999999999999999999", "1e3",
           "-99999999999999999999", " "]  # fmt: skip
BAD_STRING = ["", " ", "nan", "abc", "1e308", "x" * 5000, "\x01", "a\x1bb", "💥",
              "1,,2", ",", "nan,0,0", "1e308,0,0", "=", "st16=", "local:0", "../nosuch",
              "hip2:{d}/nosuch", "gaia:", "tcp://127.0.0.1:1", "2019-13-45T99:00:00"]  # fmt: skip
#: string options whose domain includes any word (names: a column name is checked against the
#: file when it is read, and is then refused; kept in the sweep)
FREE_STRINGS: set[str] = set()

#: values an option takes by design: ``--max-mag inf`` is "every star" (a limit beyond the
#: catalogue; availability_options.check_max_mag), so are the floats that parse to infinity
ACCEPTS = {"--max-mag": {"inf", "1e308", "1e400", "1e30000000"}}
#: the integer options that count work (trials, frames, orientations ...): 10**12 must be refused;
#: thresholds (``--pixel-threshold``, ``--n-min``) are not allocations and may be any size
COUNTS = ("trials", "frames", "orientations", "samples", "sequence", "workers", "jobs", "n-stars")

#: output options (a file, or a folder for these)
OUTPUT_DIRS = {"--maps"}
DIR_OUT_COMMANDS = {"datasheet", "trade", "report"}
#: input path options
INPUT_NAMES = {"images", "frames", "more_frames", "--centroids", "--tle", "--tolerance-json",
               "--sensors", "--against", "input_path"}  # fmt: skip
OUTPUT_KINDS = ["fifo", "chardev", "link-to-fifo", "socket", "folder", "missing-parent"]
INPUT_KINDS = ["missing", "folder", "empty", "garbage", "utf16", "fifo", "huge-png", "cut",
               "changed"]  # fmt: skip


@dataclass
class Case:
    """One run: the argument list (placeholders unfilled), what must happen, what to make."""

    index: int
    kind: str
    command: str
    argv: list[str]
    expect: str  # "refuse" (exit 2), "any" (no traceback), "signal" (130/143 or a clean end)
    make: dict[str, str] = field(default_factory=dict)  # relative path -> special file kind
    signal: str | None = None
    delay_s: float = 0.0
    note: str = ""

    def as_dict(self) -> dict:
        """The case as JSON-able data (the record lists the failures this way)."""
        return {
            "index": self.index,
            "kind": self.kind,
            "command": self.command,
            "argv": self.argv,
            "expect": self.expect,
            "make": self.make,
            "signal": self.signal,
            "delay_s": round(self.delay_s, 3),
            "note": self.note,
        }


@dataclass(frozen=True)
class Param:
    """An option or argument of a command: its flag (or name), type and whether required."""

    name: str
    kind: str  # "int", "float", "string", "path", "bool"
    required: bool
    positional: bool


def _set(argv: list[str], name: str, value: str, positional_index: int | None) -> list[str]:
    """``argv`` with option ``name`` given ``value`` (replaced if present, else appended)."""
    out = list(argv)
    if positional_index is not None:
        out[positional_index] = value
        return out
    if name in out:
        out[out.index(name) + 1] = value
        return out
    return [*out, name, value]


def _positional_slots(command: str, argv: list[str]) -> list[int]:
    """Indices of the positional arguments in the base ``argv`` (after the command's words)."""
    words = len(command.split())
    out, i = [], words
    while i < len(argv):
        if argv[i].startswith("--"):
            i += 2
            continue
        out.append(i)
        i += 1
    return out


def generate(params: dict[str, list[Param]], seed: int, n: int) -> list[Case]:
    """Draw ``n`` cases from ``seed`` over the commands of ``params`` (name -> parameters)."""
    rng = random.Random(seed)
    commands = sorted(c for c in params if c in BASE)
    kinds = ["value"] * 10 + ["output"] * 3 + ["input"] * 3 + ["usage"] + ["signal"] * 2
    kinds += ["huge"]
    cases = []
    for index in range(n):
        command = rng.choice(commands)
        kind = rng.choice(kinds)
        case = _draw(rng, index, kind, command, params[command])
        if case is None:  # the command has nothing of the kind: a value case instead
            case = _draw(rng, index, "value", command, params[command])
        cases.append(case)
    return cases


def _draw(rng, index: int, kind: str, command: str, params: list[Param]) -> Case | None:
    base = BASE[command]
    slots = _positional_slots(command, base)
    positional = [p for p in params if p.positional]
    where = {p.name: slots[i] for i, p in enumerate(positional) if i < len(slots)}
    if kind == "value":
        options = [p for p in params if p.kind in ("int", "float", "string") and not p.positional]
        options = [p for p in options if p.name not in FREE_STRINGS]
        if not options:
            return None
        p = rng.choice(options)
        pool = {"int": BAD_INT, "float": BAD_FLOAT, "string": BAD_STRING}[p.kind]
        if p.name == "--seed":  # any integer >= 0 seeds NumPy, however long
            pool = [v for v in pool if not v.isdigit()]
        pool = [v for v in pool if v not in ACCEPTS.get(p.name, ())]
        value = rng.choice(pool)
        argv = _set(base, p.name, value, None)
        return Case(index, kind, command, argv, "refuse", note=f"{p.name}={value[:40]!r}")
    if kind == "output":
        outs = [p for p in params if p.kind == "path" and p.name not in INPUT_NAMES]
        if not outs:
            return None
        p = rng.choice(outs)
        special = rng.choice(OUTPUT_KINDS)
        wants_dir = p.name in OUTPUT_DIRS or (p.name == "--out" and command in DIR_OUT_COMMANDS)
        if special == "folder":  # the other kind of thing where the output goes
            special = "file" if wants_dir or p.name == "output" else "folder"
        target = "{d}/missing/x.png" if special == "missing-parent" else "{d}/target"
        if p.name in ("--out", "--plot", "--wcs", "--explain") and not wants_dir:
            suffix = {"calibrate": ".toml", "characterize": ".toml", "ecss": ".json"}
            ext = suffix.get(command, ".png") if p.name == "--out" else ".png"
            if p.name == "--wcs":
                ext = ".wcs"
            target = (
                target.replace("/x.png", "/x" + ext)
                if special == "missing-parent"
                else (target + ext)
            )
        argv = _set(base, p.name, target, where.get(p.name))
        make = {} if special == "missing-parent" else {target[4:]: special}
        # a folder (and a figure's) missing folders are made: refused or written, cleanly
        expect = "any" if special == "missing-parent" else "refuse"
        return Case(index, kind, command, argv, expect, make=make, note=f"{p.name}:{special}")
    if kind == "input":
        ins = [p for p in params if p.kind == "path" and p.name in INPUT_NAMES]
        sensor = [p for p in params if p.name == "--sensor"]
        choices = ins + sensor
        if not choices:
            return None
        p = rng.choice(choices)
        bad = rng.choice(INPUT_KINDS)
        if p.name == "--sensor" and bad == "huge-png":
            bad = "garbage"
        ext = ".toml" if p.name == "--sensor" else {
            "--tle": ".txt", "--tolerance-json": ".json", "--centroids": ".csv",
            "input_path": ".csv", "--sensors": "", "--against": ".json",
        }.get(p.name, ".png")  # fmt: skip
        target = "{d}/in" + ext
        argv = _set(base, p.name, target, where.get(p.name))
        # a changed file may still be valid, so may a text file cut at a line's end (fewer rows);
        # track reports each unreadable frame and goes on
        text_cut = bad == "cut" and ext != ".png"
        expect = "any" if bad == "changed" or text_cut or command == "track" else "refuse"
        return Case(index, kind, command, argv, expect, make={target[4:]: "in:" + bad},
                    note=f"{p.name}:{bad}")  # fmt: skip
    if kind == "usage":
        required = [p for p in params if p.required]
        if required and rng.random() < 0.5:
            p = rng.choice(required)
            argv = list(base)
            if p.positional and p.name in where:
                # the last positional takes every word left (track's frames): drop them all
                last = p is positional[-1]
                end = slots[-1] + 1 if last else where[p.name] + 1
                del argv[where[p.name] : end]
            elif p.name in argv:
                i = argv.index(p.name)
                del argv[i : i + 2]
            return Case(index, kind, command, argv, "refuse", note=f"without {p.name}")
        flag = rng.choice(["--bogus", "-x", "--help-me", "--jsonn", "--=1"])
        return Case(index, kind, command, [*base, flag], "refuse", note=f"with {flag}")
    if kind == "signal":
        sig = rng.choice(["SIGINT", "SIGTERM"])
        delay = rng.uniform(0.02, 3.0)
        return Case(index, kind, command, list(base), "signal", signal=sig, delay_s=delay,
                    note=f"{sig} at {delay:.2f} s")  # fmt: skip
    if kind == "huge":
        counts = [p for p in params if p.kind == "int" and any(w in p.name for w in COUNTS)]
        frames = [p for p in params if p.name in ("images", "frames", "more_frames")]
        if frames and (not counts or rng.random() < 0.5):
            p = rng.choice(frames)
            target = "{d}/strip.png"
            argv = _set(base, p.name, target, where.get(p.name))
            return Case(index, kind, command, argv, "any", make={target[4:]: "in:strip"},
                        note=f"{p.name}:1x100000")  # fmt: skip
        if not counts:
            return None
        p = rng.choice(counts)
        argv = _set(base, p.name, str(10**12), None)
        return Case(index, kind, command, argv, "refuse", note=f"{p.name}=10**12")
    raise ValueError(kind)
