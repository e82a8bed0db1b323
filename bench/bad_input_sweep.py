"""Bad-input and fault sweep over every command (issue 50's acceptance), seeded.

    python bench/bad_input_sweep.py [--seed N] [--cases N] [--jobs N] [--out FILE]

Draws the cases from the seed (bench/sweep_cases.py: bad values, special outputs, bad inputs,
usage errors, SIGINT / SIGTERM at a random moment, huge counts and frames; every command of the
app), runs each as its own process and judges it. A case is clean when:

* a case that must be refused exits 2 with one line (``error: ...``), or with typer's usage
  message for a malformed command line (counted apart as ``usage``);
* a signalled run exits 130 (SIGINT) or 143 (SIGTERM) with that one line, or had finished
  cleanly before the signal came;
* nothing prints a traceback; nothing exits 0 having been given what it must refuse (silent);
* the case's folder holds, after a refusal or a signal, exactly what it held before (no partial
  output, no temporary), its ``TMPDIR`` is empty, no process of it outlives it;
* every FIFO, device, link and socket made where an output goes is still there, unchanged;
* its peak resident memory (including the pages it shares with the forking parent) is under
  2 GB.

Each case runs in a child forked from a parent that has imported every command (a fresh
interpreter per case would spend 1-2 s importing; forking spends milliseconds), in its own
folder, process group and ``TMPDIR``, with its output to files and its address space capped
(2.5 GB above the parent's) so that a runaway allocation fails the case, not the machine.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import json
import os
import platform
import random
import resource
import shutil
import signal
import socket
import stat
import sys
import tempfile
import threading
import time
import traceback
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sweep_cases import Case, Param, generate
from sweep_inputs import Fixtures, make

#: the peak resident memory a run may reach, bytes
MAX_RSS_BYTES = 2_000_000_000
#: how long a case may run before it is killed (and failed), s
TIMEOUT_S = 90.0
#: a server command still serving after this long accepted what it was given, s
SERVER_S = 8.0
EXITS = {
    "SIGINT": (130, "error: interrupted (Ctrl-C); "),
    "SIGTERM": (143, "error: terminated (SIGTERM); "),
}


def command_params() -> dict[str, list[Param]]:
    """Every command of the app (``"availability static"``) -> its parameters, from typer."""
    import typer

    from starsense.cli.app import build_app

    kinds = {"Int": "int", "Float": "float", "String": "string", "TyperPath": "path"}
    out: dict[str, list[Param]] = {}

    def walk(cmd, path):
        subs = getattr(cmd, "commands", None)
        if subs:
            for name, sub in subs.items():
                walk(sub, [*path, name])
            return
        params = []
        for p in cmd.params:
            kind = kinds.get(type(p.type).__name__.replace("ParamType", ""), "bool")
            if type(p.type).__name__ == "BoolParamType" or getattr(p, "is_flag", False):
                kind = "bool"
            positional = not p.opts or not p.opts[0].startswith("-")
            name = p.name if positional else p.opts[0]
            params.append(Param(name, kind, bool(p.required), positional))
        out[" ".join(path)] = params

    walk(typer.main.get_command(build_app()), [])
    return out


# -- running ---------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _fill(argv: list[str], case_dir: Path, fixtures: Fixtures) -> list[str]:
    values = {
        "d": str(case_dir),
        "frame": str(fixtures.frame),
        "csv": str(fixtures.csv),
        "toml": str(fixtures.toml),
        "tle": str(fixtures.tle),
        "port": str(_free_port()),
    }
    out = []
    for a in argv:
        for k, v in values.items():
            a = a.replace("{" + k + "}", v)
        out.append(a)
    return out


def _child(argv: list[str], case_dir: Path, tmp: Path, cap: int) -> None:  # pragma: no cover
    """In the forked child: run the command line and exit with its status."""
    code = 70
    try:
        os.setpgid(0, 0)
        os.chdir(case_dir)
        r, w = os.pipe()
        os.close(w)
        os.dup2(r, 0)  # stdin at its end: nothing to read
        for fd, name in ((1, "stdout"), (2, "stderr")):
            out = os.open(case_dir.parent / f"{case_dir.name}.{name}", os.O_WRONLY | os.O_CREAT)
            os.dup2(out, fd)
        # the streams of a plain process (a test runner's capture objects are not fds 1 and 2)
        sys.stdout = open(1, "w", encoding="utf-8", closefd=False, buffering=1)
        sys.stderr = open(2, "w", encoding="utf-8", closefd=False, buffering=1)
        warnings.resetwarnings()  # Python's own filters, not a test run's warnings-as-errors
        for category in (
            DeprecationWarning,
            PendingDeprecationWarning,
            ImportWarning,
            ResourceWarning,
        ):
            warnings.simplefilter("ignore", category)
        os.environ["TMPDIR"] = str(tmp)
        tempfile.tempdir = None
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        from starsense.cli import main

        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:
        traceback.print_exc()
    finally:
        # the end of a plain interpreter: threads joined, then the exit functions (the Dask
        # cluster's and multiprocessing's: skipped, they left its resource tracker running)
        with contextlib.suppress(BaseException):
            threading._shutdown()
        with contextlib.suppress(BaseException):
            atexit._run_exitfuncs()
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code if isinstance(code, int) and 0 <= code < 256 else 1)


def _snapshot(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _still(path: Path, kind: str) -> bool:
    if kind.startswith("in:"):  # an input: read, not written
        return True
    try:
        st = os.lstat(path)
    except OSError:
        return False
    if kind == "fifo":
        return stat.S_ISFIFO(st.st_mode)
    if kind == "chardev":
        return stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3)
    if kind == "link-to-fifo":
        return stat.S_ISLNK(st.st_mode) and stat.S_ISFIFO(os.stat(path).st_mode)
    if kind == "socket":
        return stat.S_ISSOCK(st.st_mode)
    return True


class Run:
    """One case in flight: its folders, its forked process and what was made for it."""

    def __init__(self, case: Case, work: Path, fixtures: Fixtures, cap: int) -> None:
        self.case = case
        self.dir = work / f"c{case.index}"
        self.tmp = work / f"t{case.index}"
        self.dir.mkdir()
        self.tmp.mkdir()
        self.held: list = []
        rng = random.Random(case.index)
        for rel, kind in case.make.items():
            make(self.dir / rel, kind, fixtures, rng, self.held)
        self.before = _snapshot(self.dir)
        self.argv = _fill(case.argv, self.dir, fixtures)
        sys.stdout.flush()
        sys.stderr.flush()
        self.t0 = time.monotonic()
        self.pid = os.fork()
        if self.pid == 0:  # pragma: no cover - the child
            _child(self.argv, self.dir, self.tmp, cap)
        self.signalled = False
        self.server_stopped = False
        self.killed = False

    def poll(self) -> dict | None:
        """Advance the case (signal, time limit); return its result once it has ended."""
        pid, status, usage = os.wait4(self.pid, os.WNOHANG)
        elapsed = time.monotonic() - self.t0
        if pid == 0:
            if self.case.signal and not self.signalled and elapsed >= self.case.delay_s:
                os.kill(self.pid, getattr(signal, self.case.signal))
                self.signalled = True
            elif self.case.command == "design" and not self.signalled and elapsed > SERVER_S:
                os.kill(self.pid, signal.SIGTERM)  # serving: it accepted its command line
                self.signalled = self.server_stopped = True
            elif elapsed > TIMEOUT_S and not self.killed:
                os.killpg(self.pid, signal.SIGKILL)
                self.killed = True
            return None
        return self.judge(os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024, elapsed)

    def judge(self, code: int, rss: int, elapsed: float) -> dict:
        """The case's result: its outcome (``clean`` or the first fault found) and evidence."""
        case = self.case
        err = (self.dir.parent / f"{self.dir.name}.stderr").read_text(errors="replace")
        out = (self.dir.parent / f"{self.dir.name}.stdout").read_text(errors="replace")
        # progress ("starsense: building the identification database ...") and warnings in
        # words may come before the one line that ends a run
        said = err.strip().splitlines()
        lines = [x for x in said if not x.startswith(("starsense: ", "warning: "))]
        orphans = _orphans(self.pid)
        after = _snapshot(self.dir)
        tmp_left = sorted(os.listdir(self.tmp))
        temporaries = [p for p in after if ".starsense-" in p or "starsense-dask-" in p]
        replaced = [r for r, k in case.make.items() if not _still(self.dir / r, k)]
        usage = code == 2 and bool(lines) and lines[0].startswith("Usage:") and "Error" in err
        one_line = code == 2 and len(lines) == 1 and lines[0].startswith("error: ")
        outcome, form = "clean", ""
        if "Traceback" in err or "Traceback" in out:
            outcome = "traceback"
        elif self.killed:
            outcome = "timeout"
        elif replaced:
            outcome = "device replaced"
        elif rss > MAX_RSS_BYTES:
            outcome = "memory"
        elif orphans:
            outcome = "orphan processes"
        elif tmp_left or temporaries:
            outcome = "left-over files"
        elif case.expect == "signal" and self.signalled:
            want, prefix = EXITS[case.signal]
            if code in (0, 1):  # ended before the signal took: judged as a normal run
                form = "finished first"
            elif code == 2 and (one_line or usage):
                form = "refused first"
            elif code != want or len(lines) != 1 or not lines[0].startswith(prefix):
                outcome = "bad exit"
            elif lines[0].endswith("nothing written") and after != self.before:
                outcome = "left-over files"
            else:  # nothing written, or what was (complete, no temporaries) named
                form = "signal" if after == self.before else "signal, written before it"
        elif self.server_stopped or (case.expect == "refuse" and code in (0, 1)):
            warned = not lines and any(x.startswith("warning: ") for x in said)
            if warned and not self.server_stopped:
                form = "warned"  # the "refused or warned in words"
            else:
                outcome = "silent"
        elif code == 2:
            if not (one_line or usage):
                outcome = "not one line"
            elif case.expect == "refuse" and after != self.before:
                outcome = "left-over files"
            else:
                form = "usage" if usage else "one line"
        elif code not in (0, 1):
            outcome = "bad exit"
        else:
            form = f"exit {code}"
        for s in self.held:
            s.close()
        return {
            **case.as_dict(),
            "outcome": outcome,
            "form": form,
            "exit": code,
            "signalled": self.signalled and not self.server_stopped,
            "seconds": round(elapsed, 2),
            "peak_rss_mb": round(rss / 1e6, 1),
            "stderr_tail": "\n".join(said[-6:])[-1500:],
            "left": sorted(after - self.before)[:8],
            "tmpdir_left": tmp_left[:8],
            "replaced": replaced,
            "orphans": orphans,
        }


def _orphans(pgid: int, wait_s: float = 3.0) -> list[str]:
    """Processes of the case's process group alive ``wait_s`` after it (killed once counted).

    A moment is allowed: multiprocessing's resource tracker ends when the last process holding
    its pipe has (it cleans up after them), as it does after any command.
    """
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except OSError:
            return []
        if not _group(pgid):
            return []
        time.sleep(0.05)
    found = _group(pgid)
    with contextlib.suppress(OSError):
        os.killpg(pgid, signal.SIGKILL)
    return found


def _group(pgid: int) -> list[str]:
    """The live processes of process group ``pgid``, with their command lines."""
    found = []
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as fh:
                    fields = fh.read().rsplit(") ", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] != "Z":
                with contextlib.suppress(OSError), open(f"/proc/{name}/cmdline", "rb") as fh:
                    name += " " + fh.read()[:120].replace(b"\0", b" ").decode(errors="replace")
                found.append(name)
    return found


def _address_space() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def sweep(seed: int, n: int, jobs: int = 2, work: Path | None = None, echo=print) -> dict:
    """Run ``n`` cases drawn from ``seed``; return the record (counts, failures, timing)."""
    params = command_params()
    cases = generate(params, seed, n)
    own = work is None
    work = Path(tempfile.mkdtemp(prefix="ss-sweep-")) if own else work
    try:
        fixtures = Fixtures(work)
        cap = _address_space() + 2_500_000_000
        results: list[dict] = []
        pending, running = list(cases), []
        t0 = time.monotonic()
        while pending or running:
            while pending and len(running) < jobs:
                running.append(Run(pending.pop(0), work, fixtures, cap))
            for run in list(running):
                result = run.poll()
                if result is not None:
                    running.remove(run)
                    results.append(result)
                    if result["outcome"] != "clean":
                        echo(
                            f"FAIL {result['outcome']}: case {result['index']} "
                            f"{' '.join(run.argv)[:160]!r}: {result['stderr_tail'][-300:]!r}"
                        )
                    shutil.rmtree(run.dir, ignore_errors=True)
                    shutil.rmtree(run.tmp, ignore_errors=True)
            time.sleep(0.01)
        return _record(seed, n, params, results, time.monotonic() - t0)
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


def _count(results: list[dict], key: str) -> dict:
    out: dict[str, int] = {}
    for r in results:
        out[r[key]] = out.get(r[key], 0) + 1
    return dict(sorted(out.items()))


def _record(seed: int, n: int, params: dict, results: list[dict], seconds: float) -> dict:
    results.sort(key=lambda r: r["index"])
    failures = [r for r in results if r["outcome"] != "clean"]
    return {
        "seed": seed,
        "cases": n,
        "commands": sorted(params),
        "commands_swept": sorted({r["command"] for r in results}),
        "outcomes": _count(results, "outcome"),
        "forms": _count(results, "form"),
        "kinds": _count(results, "kind"),
        "clean": sum(r["outcome"] == "clean" for r in results),
        # a signal case whose command had ended before its moment came was judged as a plain run
        "signals_delivered": sum(r["kind"] == "signal" and r["signalled"] for r in results),
        "peak_rss_mb_max": max((r["peak_rss_mb"] for r in results), default=0.0),
        "seconds": round(seconds, 1),
        "failures": failures,
        "machine": {
            "python": platform.python_version(),
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average": os.getloadavg(),
        },
    }


def main() -> int:
    """Run the sweep from the command line; print the summary; write the JSON record."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=None, help="default: drawn and printed")
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="JSON record to write")
    args = parser.parse_args()
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(10**9)
    print(f"seed {seed}, {args.cases} cases", flush=True)
    record = sweep(seed, args.cases, args.jobs)
    print(json.dumps({k: v for k, v in record.items() if k != "failures"}, indent=1))
    if args.out is not None:
        args.out.write_text(json.dumps(record, indent=1) + "\n")
    return 0 if record["clean"] == record["cases"] else 1


if __name__ == "__main__":
    sys.exit(main())
