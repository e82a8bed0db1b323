"""Every common image format a camera writes, solved on a rendered frame of known truth.

One 8-bit frame of the camera of tests/_support/camera8.py (6 x 4.5 deg on 1024 x 768 pixels,
21 arcsec/px, background at 1 count with 0.7 counts of noise clipped at zero) is written in each
format (as 8-bit counts, or scaled to 16 bits, or as floats, or as colour) and solved from the
file knowing only the field. Every format must give the attitude of the render: within 1 px
(21 arcsec) across the boresight and 0.15 deg in roll, the tolerances of
tests/solve/test_solve_any_camera.py (a wrong identification is off by degrees). A lossless
format must also give back the frame's counts exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from camera8 import FOV_RAD, camera8, frame8

from starsense.catalog import load_catalog
from starsense.geometry.attitude import small_rotation_angles
from starsense.solve.bayer import bayer_hint, bin_bayer
from starsense.solve.frames import load_image
from starsense.solve.solver import Solver

ARCSEC_PER_RAD = 180 / math.pi * 3600
#: the colour response of a raw mosaic's R, G, G, B pixels to the (grey) scene
BAYER_WEIGHTS = {"RGGB": (0.55, 1.0, 1.0, 0.4), "GBRG": (1.0, 0.4, 0.55, 1.0)}


@pytest.fixture(scope="module")
def truth():
    catalog = load_catalog("hipparcos")
    image, att, _ = frame8(camera8(bias_counts=1.0), catalog, 140.0, -20.0, 250.0, seed=3)
    return image, att


@pytest.fixture(scope="module")
def solver():
    return Solver(fov_rad=FOV_RAD)


def _right(sol, att):
    assert sol.solved, sol.message
    err = np.abs(small_rotation_angles(att, sol.rotation)) * ARCSEC_PER_RAD
    assert max(err[:2]) < 21 and err[2] < 540, err


def _pillow(image, path, mode=None, **save):
    from PIL import Image

    im = Image.fromarray(image)
    if mode == "P":  # a palette of 256 greys, index = count: lossless
        im = im.convert("L")
        im = im.convert("P")
        im.putpalette([v for g in range(256) for v in (g, g, g)])
        im.putdata(image.ravel().tolist())
    elif mode is not None:
        im = im.convert(mode)
    im.save(path, **save)


def _tifffile(image, path, **kw):
    import tifffile

    tifffile.imwrite(path, image, **kw)


def _fits(image, path, how):
    from astropy.io import fits

    if how == "primary":
        fits.PrimaryHDU(image).writeto(path)
    elif how == "extension":  # an empty primary, a table, then the image
        table = fits.BinTableHDU.from_columns([fits.Column(name="a", format="E", array=[1.0])])
        fits.HDUList([fits.PrimaryHDU(), table, fits.ImageHDU(image)]).writeto(path)
    elif how == "tile-compressed":
        fits.HDUList([fits.PrimaryHDU(), fits.CompImageHDU(image)]).writeto(path)
    elif how == "cube":
        fits.PrimaryHDU(image[None]).writeto(path)


# name, writer(image8, path), exact: the counts read back are the frame's (times the scale)
FORMATS = {
    "bmp": (lambda a, p: _pillow(a, p), ".bmp", 1),
    "png 8-bit grey": (lambda a, p: _pillow(a, p), ".png", 1),
    "png 16-bit grey": (lambda a, p: _pillow(a.astype(np.uint16) * 257, p), ".png", 257),
    "png rgb of grey": (lambda a, p: _pillow(a, p, "RGB"), ".png", 1),
    "png rgba of grey": (lambda a, p: _pillow(a, p, "RGBA"), ".png", 1),
    "png grey + alpha": (lambda a, p: _pillow(a, p, "LA"), ".png", 1),
    "png palette": (lambda a, p: _pillow(a, p, "P"), ".png", 1),
    "tiff 8-bit lzw": (lambda a, p: _pillow(a, p, compression="tiff_lzw"), ".tif", 1),
    "tiff 16-bit deflate": (
        lambda a, p: _tifffile(a.astype(np.uint16) * 257, p, compression="zlib"),
        ".tiff",
        257,
    ),
    "tiff 32-bit integer": (lambda a, p: _tifffile(a.astype(np.uint32) * 65537, p), ".tif", 65537),
    "tiff float": (lambda a, p: _pillow(a.astype(np.float32), p), ".tif", 1),
    "tiff 16-bit rgb": (
        lambda a, p: _tifffile(
            np.repeat(a[..., None], 3, -1).astype(np.uint16) * 257, p, photometric="rgb"
        ),
        ".tif",
        257,
    ),
    "jpeg 95": (lambda a, p: _pillow(a, p, quality=95), ".jpg", None),
    "fits primary": (lambda a, p: _fits(a.astype(np.int16), p, "primary"), ".fits", 1),
    "fits extension": (lambda a, p: _fits(a.astype(np.float32), p, "extension"), ".fit", 1),
    "fits tile-compressed": (
        lambda a, p: _fits(a.astype(np.int16), p, "tile-compressed"),
        ".fits",
        1,
    ),
    "fits 1 x H x W cube": (lambda a, p: _fits(a.astype(np.int16), p, "cube"), ".fts", 1),
}


@pytest.mark.parametrize("name", list(FORMATS))
def test_every_format_solves_to_the_rendered_attitude(tmp_path, truth, solver, name):
    image, att = truth
    write, suffix, scale = FORMATS[name]
    path = tmp_path / f"frame{suffix}"
    write(image, path)
    got = load_image(path)
    assert got.shape == image.shape
    if scale is not None:  # lossless: the counts themselves
        assert np.array_equal(got, image.astype(np.int64) * scale)
    assert bayer_hint(got) is None  # a monochrome frame is not taken for a mosaic
    _right(solver.solve_file(path), att)


def test_colour_frame_solves_on_its_luminance(tmp_path, truth, solver):
    image, att = truth
    rgb = np.stack([image, image, image // 2], axis=-1).astype(np.uint8)  # a tinted frame
    _pillow(rgb, tmp_path / "c.png")
    got = load_image(tmp_path / "c.png")
    # BT.601 luminance: 0.299 R + 0.587 G + 0.114 B
    assert np.allclose(got, 0.886 * image + 0.114 * (image // 2))
    _right(solver.solve_file(tmp_path / "c.png"), att)


def _mosaic(image, pattern):
    """A raw mosaic of a grey scene: each pixel of ``image`` becomes a 2 x 2 colour cell."""
    w = np.array(BAYER_WEIGHTS[pattern]).reshape(2, 2)
    up = np.kron(image.astype(np.float32), np.ones((2, 2), np.float32))
    return up * np.tile(w, image.shape).astype(np.float32)


@pytest.mark.parametrize("pattern", list(BAYER_WEIGHTS))
def test_bayer_mosaic_is_noted_then_solved_binned(tmp_path, truth, solver, pattern):
    from astropy.io import fits

    image, att = truth
    path = tmp_path / "raw.fits"
    fits.PrimaryHDU(_mosaic(image, pattern)).writeto(path)
    raw = load_image(path)
    hint = bayer_hint(raw)
    assert hint is not None and "--bayer" in hint
    binned = load_image(path, bayer=pattern)
    # the sum of each cell is the scene times the summed response, exactly
    total = sum(BAYER_WEIGHTS[pattern])
    np.testing.assert_allclose(binned, image * total, rtol=1e-6)
    np.testing.assert_array_equal(bin_bayer(raw, pattern), binned)
    sol = solver.solve_file(path, bayer=pattern)
    _right(sol, att)
    assert sol.notes == ()
    # read as it is, a mosaic gets the note (a corner of sky: quick to give up on)
    fits.PrimaryHDU(_mosaic(image[:48, :64], pattern)).writeto(tmp_path / "corner.fits")
    unbinned = solver.solve_file(tmp_path / "corner.fits")
    assert not unbinned.solved and any("Bayer mosaic" in n for n in unbinned.notes)


def _hint_statistics(image):
    """The hint's statistics as first written: the frame converted to float32, then sliced."""
    a = np.asarray(image)
    a = a[: a.shape[0] // 2 * 2, : a.shape[1] // 2 * 2].astype(np.float32)
    cap = np.float32(np.percentile(a[::3, ::3], 99.0))
    lattices = [np.minimum(a[r::2, c::2], cap) for r in (0, 1) for c in (0, 1)]
    return [float(s.mean()) for s in lattices], float(np.mean([s.std() for s in lattices]))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32, np.float32, np.float64])
def test_bayer_hint_reads_the_frame_as_float32(dtype):
    # the hint converts each sub-lattice as it caps it: the same float32 values (and so the same
    # means and noise, bit for bit) as converting the whole frame first
    rng = np.random.default_rng(3)
    levels = np.array([[40.0, 70.0], [72.0, 120.0]])  # greens alike on one diagonal
    frame = rng.normal(np.tile(levels, (61, 83)), 6.0).clip(0, 250).astype(dtype)
    med, noise = _hint_statistics(frame)
    hint = bayer_hint(frame)
    assert hint is not None
    assert f"sit at {', '.join(f'{m:.1f}' for m in med)} counts, noise {noise:.1f})" in hint
