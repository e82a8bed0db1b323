"""Rendered sequences: the attitude carried on by the body rate, one truth per frame."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from starsense.cli import main
from starsense.errors import InputError
from starsense.geometry.attitude import angular_separation, radec_to_vectors
from starsense.render.scene import render_frame
from starsense.render.sequence import frame_seeds, render_sequence, sequence_paths


def test_sequence_frames_follow_the_rate(st16, attitude, catalog):
    w = np.radians([0.3, -0.2, 0.5])
    frames = list(
        render_sequence(
            st16, attitude, catalog, n_frames=3, interval_s=0.5, rate_rad_s=w, seed=7, noise=False
        )
    )
    assert [f.truth.time_s for f in frames] == [0.0, 0.5, 1.0]
    seeds = [f.truth.seed for f in frames]
    assert seeds == frame_seeds(7, 3) and len(set(seeds)) == 3
    for k, f in enumerate(frames):
        # frame k is the lone frame rendered at A_k = R(-w t_k) A_0 (render/scene.py convention)
        a_k = Rotation.from_rotvec(-w * 0.5 * k) * attitude
        assert (f.truth.attitude * a_k.inv()).magnitude() < 1e-12
        lone = render_frame(st16, a_k, catalog, rate_rad_s=w, noise=False)
        np.testing.assert_array_equal(f.image, lone.image)
        assert f.truth.rate_rad_s == tuple(w)


def test_sequence_bad_input(st16, attitude, catalog):
    with pytest.raises(InputError, match="shorter than the exposure"):
        next(render_sequence(st16, attitude, catalog, n_frames=2, interval_s=0.05))
    with pytest.raises(InputError, match="n_frames"):
        next(render_sequence(st16, attitude, catalog, n_frames=0, interval_s=0.5))
    with pytest.raises(InputError, match="seed"):
        next(render_sequence(st16, attitude, catalog, n_frames=2, interval_s=0.5, rng=3))


def test_sequence_paths():
    names = [p.name for p in sequence_paths("out/frame.tiff", 3)]
    assert names == ["frame_000.tiff", "frame_001.tiff", "frame_002.tiff"]
    assert sequence_paths("f.fits", 1001)[-1].name == "f_1000.fits"


def test_cli_render_sequence_writes_frames_and_truth(tmp_path, capsys):
    out = tmp_path / "frame.tiff"
    code = main(
        [
            "render",
            "--sensor",
            "st16",
            "--ra-deg",
            "80",
            "--dec-deg",
            "20",
            "--roll-deg",
            "10",
            "--rate-deg-s",
            "0.5,0.2,0.1",
            "--sequence",
            "3",
            "--interval-s",
            "0.5",
            "--seed",
            "3",
            "--max-mag",
            "5",
            "--out",
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().err
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [f"frame_00{k}.tiff{ext}" for k in range(3) for ext in ("", ".json")]
    truth = [json.loads((tmp_path / f"frame_00{k}.tiff.json").read_text()) for k in range(3)]
    assert [t["time_s"] for t in truth] == [0.0, 0.5, 1.0]
    assert truth[1]["rate_rad_s"] == pytest.approx(np.radians([0.5, 0.2, 0.1]).tolist())
    # the attitude of frame 1 is frame 0's turned by the rate over 0.5 s (0.28 deg): the
    # boresights differ by |w_xy| dt to first order (the roll part leaves the boresight)
    b = [
        radec_to_vectors(np.radians(t["attitude"]["ra_deg"]), np.radians(t["attitude"]["dec_deg"]))
        for t in truth
    ]
    assert float(angular_separation(b[0], b[1])) == pytest.approx(
        np.hypot(*np.radians([0.5, 0.2])) * 0.5, rel=1e-3
    )


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--sequence", "3"], "go together"),
        (["--sequence", "3", "--interval-s", "0.01"], "at least the exposure"),
        (["--sequence", "0", "--interval-s", "1"], "--sequence"),
        (["--sequence", "2", "--interval-s", "1", "--areas"], "--areas"),
    ],
)
def test_cli_render_sequence_bad_input(tmp_path, capsys, extra, match):
    code = main(["render", "--sensor", "st16", "--out", str(tmp_path / "f.tiff"), *extra])
    assert code == 2
    assert match in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
