"""The release: the wheel installs into a clean virtual environment with no C compiler reachable,
and runs a datasheet there (what `make check-dist` does, from a test)."""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _run(cmd, **kwargs) -> subprocess.CompletedProcess:
    done = subprocess.run(cmd, capture_output=True, text=True, check=False, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, cmd))}: {done.stderr[-3000:]}"
    return done


@pytest.mark.slow  # a wheel built, a venv made and its dependencies installed: about a minute
def test_the_wheel_installs_without_a_compiler_and_runs_a_datasheet(tmp_path):
    pytest.importorskip("build", reason="the dev extra's `build` makes the wheel")
    _run([sys.executable, "-m", "build", "--wheel", "--outdir", str(tmp_path / "dist"), str(REPO)])
    wheels = list((tmp_path / "dist").glob("starsense-*.whl"))
    assert len(wheels) == 1, wheels
    env_dir = tmp_path / "env"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    # no compiler: anything that would build C code on install fails at once
    env = os.environ | {"CC": "/bin/false", "CXX": "/bin/false", "LDSHARED": "/bin/false"}
    env.pop("PYTHONPATH", None)  # the clean environment's own site-packages only
    _run([str(py), "-m", "pip", "install", "--quiet", str(wheels[0])], env=env)
    env["STARSENSE_CACHE_DIR"] = str(tmp_path / "cache")
    sheet = [str(env_dir / "bin" / "starsense"), "datasheet", "--sensor", "st16", "--trials", "5"]
    done = _run(sheet, env=env, cwd=tmp_path)
    assert done.stdout.startswith("st16 datasheet"), done.stdout[:500]
    # the installed package is the wheel's, not this checkout's
    probe = [str(py), "-c", "import starsense; print(starsense.__file__)"]
    where = _run(probe, env=env, cwd=tmp_path)
    assert str(env_dir) in where.stdout, where.stdout
