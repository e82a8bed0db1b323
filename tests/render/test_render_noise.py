"""Detector response: shot and read noise, gain, bias, quantisation, saturation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.render.noise import apply_noise, as_generator, quantise
from starsense.render.star_stamp import render_star_stamp


def with_detector(sensor, **changes):
    return sensor.with_(detector=dataclasses.replace(sensor.detector, **changes))


def test_saturates_at_4095_for_12_bits(st16) -> None:
    # A very bright static star (1e7 e- x 6.5 counts/e-): the centre pixels saturate at
    # 2^12 - 1 = 4095 and nothing exceeds it, with and without noise.
    for noise in (False, True):
        counts = render_star_stamp(st16, 1e7, rng=3, noise=noise)
        assert counts.dtype == np.uint16
        assert counts.max() == 4095


@pytest.mark.parametrize(("bits", "dtype"), [(8, np.uint16), (16, np.uint16), (20, np.uint32)])
def test_dtype_and_saturation_follow_the_bit_depth(st16, bits, dtype) -> None:
    # bias 0: an 8-bit ADC over the ST-16's 168-count bias leaves 87 counts, below its 120-count
    # lit threshold, and such a sensor is refused (test_sensor_sanity); the dtype is the point here
    sensor = with_detector(st16, bit_depth=bits, full_well_e=1e9, bias_counts=0.0)
    counts = apply_noise(np.full((8, 8), 1e8), sensor, rng=1)
    assert counts.dtype == dtype
    assert counts.max() == 2**bits - 1
    assert quantise(np.full((2, 2), 1e8), sensor).max() == 2**bits - 1


def test_full_well_clips_before_the_gain(st16) -> None:
    # 16-bit ADC with gain 1: 50,000 e- in a well of 8,000 e- reads 8,000 counts over the bias
    # (noiseless): the well clips the charge, the bias is added after it.
    sensor = with_detector(st16, bit_depth=16, gain_counts_per_e=1.0, full_well_e=8000.0)
    bias = sensor.detector.bias_counts
    counts = quantise(np.array([50_000.0, 100.0]), sensor) - bias
    assert counts.tolist() == [8000, 100]


def test_quantisation_rounds_to_nearest(st16) -> None:
    # 6.5 counts/e-: 1 e- -> 6.5 -> 6 (round half to even), 1.1 e- -> 7.15 -> 7, 0.2 -> 1.3 -> 1;
    # bias 0, so the half count is rounded on its own (an odd bias would round it up)
    sensor = with_detector(st16, bias_counts=0.0)
    assert quantise(np.array([1.0, 1.1, 0.2, 0.0]), sensor).tolist() == [6, 7, 1, 0]


def test_shot_and_read_noise_statistics(st16) -> None:
    # Flat field of lam = 50 e- on 400,000 pixels: counts less the bias (168, an integer: 7.4
    # sigma, never clipped) = round(6.5 (Poisson(50) + N(0, 3.5^2))).
    # Mean 6.5 x 50 = 325 (rounding is unbiased); variance 6.5^2 (50 + 3.5^2) + 1/12 = 2630.
    # Standard errors: mean 0.08 counts, variance 2630 x sqrt(2 / n) ~ 5.9 (Gaussian-like).
    # Ask 5 standard errors.
    n = 400_000
    counts = apply_noise(np.full(n, 50.0), st16, rng=11).astype(float) - st16.detector.bias_counts
    assert counts.mean() == pytest.approx(325.0, abs=5 * 0.081)
    var = 6.5**2 * (50 + 3.5**2) + 1 / 12
    assert counts.var() == pytest.approx(var, abs=5 * var * np.sqrt(2 / n))


def test_background_is_read_noise_only_without_dark_current(st16) -> None:
    # st16 (no dark current) with its bias set to 0, so the ADC clips the noise: zero-signal
    # pixels read round(6.5 N(0, 3.5^2)) clipped at
    # 0: P(count = 0) = P(6.5 x N < 0.5) = Phi(0.5 / 22.75) = 0.5088; mean of the clipped
    # positive part 22.75 / sqrt(2 pi) = 9.076. With 1e6 pixels: tolerances of 5 standard errors
    # (0.0025 and 0.07 counts).
    sensor = with_detector(st16, bias_counts=0.0)
    counts = apply_noise(np.zeros((1000, 1000), np.float32), sensor, rng=5).astype(float)
    assert (counts == 0).mean() == pytest.approx(0.5088, abs=0.0025)
    assert counts.mean() == pytest.approx(9.076, abs=0.07)


def test_dark_current_and_bias(st16) -> None:
    # 200 e-/s x 0.1 s = 20 e- of dark charge, gain 1, bias 100 counts, no read noise:
    # mean 120, variance 20 (Poisson) + 1/12 (rounding); 1e5 pixels, 5 standard errors.
    sensor = with_detector(
        st16, dark_current_e_s=200.0, bias_counts=100.0, read_noise_e=0.0, gain_counts_per_e=1.0
    )
    counts = apply_noise(np.zeros(100_000), sensor, rng=2).astype(float)
    assert counts.mean() == pytest.approx(120.0, abs=5 * np.sqrt(20 / 1e5))
    assert counts.var() == pytest.approx(20 + 1 / 12, abs=5 * 20 * np.sqrt(2 / 1e5))


def test_seeded_noise_is_reproducible(st16) -> None:
    e = np.zeros((50, 60))
    e[20:30, 25:35] = 300.0
    a = apply_noise(e, st16, rng=42)
    assert np.array_equal(a, apply_noise(e, st16, rng=np.random.default_rng(42)))
    assert not np.array_equal(a, apply_noise(e, st16, rng=43))


def test_bad_input(st16) -> None:
    with pytest.raises(InputError, match="finite and >= 0"):
        apply_noise(np.array([1.0, -2.0]), st16, rng=0)
    with pytest.raises(InputError, match="finite and >= 0"):
        apply_noise(np.array([1.0, np.nan]), st16, rng=0)
    with pytest.raises(InputError, match="finite and >= 0"):
        quantise(np.array([np.inf]), st16)
    with pytest.raises(InputError, match="exposure_s"):
        apply_noise(np.zeros(3), st16, rng=0, exposure_s=-1.0)
    with pytest.raises(InputError, match="rng"):
        as_generator("seed")
    gen, seed = as_generator(None)
    assert isinstance(seed, int) and isinstance(gen, np.random.Generator)
