"""Reading centroid lists (starsense.solve.centroids): CSV and astrometry.net xylists."""

from __future__ import annotations

import numpy as np
import pytest

from starsense.errors import InputError
from starsense.solve.centroids import read_centroids


def test_csv_without_header_blank_separated_with_comments(tmp_path):
    p = tmp_path / "c.txt"
    p.write_text("# from my centroider\n10.5 20.25 300\n\n30 40 100\n")
    got = read_centroids(p)
    np.testing.assert_array_equal(got.xy, [[10.5, 20.25], [30, 40]])
    np.testing.assert_array_equal(got.flux, [300, 100])
    assert got.image_size is None


def test_csv_two_columns_has_no_flux(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("1,2\n3,4\n")
    got = read_centroids(p)
    assert got.flux is None and got.xy.shape == (2, 2)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no centroids \\(the file is empty\\)"),
        ("# only a comment\n", "no centroids"),
        ("x,y\n", "a header only"),
        ("a,b\n1,2\n", "line 1: header .* has no 'x' column"),
        ("1,2,3,4\n", "line 1: expected 2 or 3 columns"),
        ("1,2\n3\n", "line 2: expected 2 columns"),
        ("1,2\n3,nan\n", "line 2, column 2: not finite"),
    ],
)
def test_csv_errors_name_the_line(tmp_path, text, message):
    p = tmp_path / "c.csv"
    p.write_text(text)
    with pytest.raises(InputError, match=message):
        read_centroids(p)


def test_xylist_is_converted_from_fits_pixels(tmp_path):
    from astropy.io import fits

    cols = [
        fits.Column(name="X", format="E", array=np.array([1.0, 100.5])),
        fits.Column(name="Y", format="E", array=np.array([1.0, 50.25])),
    ]
    p = tmp_path / "c.xyls"
    fits.HDUList([fits.PrimaryHDU(), fits.BinTableHDU.from_columns(cols)]).writeto(p)
    got = read_centroids(p)
    # FITS (1, 1) is the centre of the first pixel: starsense (0, 0)
    np.testing.assert_allclose(got.xy, [[0.0, 0.0], [99.5, 49.25]])
    assert got.flux is None and got.image_size is None


def test_xylist_without_a_table_or_columns(tmp_path):
    from astropy.io import fits

    p = tmp_path / "image.fits"
    fits.PrimaryHDU(np.zeros((4, 4))).writeto(p)
    with pytest.raises(InputError, match="no BINTABLE extension"):
        read_centroids(p)
    q = tmp_path / "t.fits"
    cols = [fits.Column(name="X", format="E", array=np.array([1.0]))]
    fits.HDUList([fits.PrimaryHDU(), fits.BinTableHDU.from_columns(cols)]).writeto(q)
    with pytest.raises(InputError, match="the table has no Y column"):
        read_centroids(q)
    with pytest.raises(InputError, match="centroid file not found"):
        read_centroids(tmp_path / "missing.csv")


@pytest.mark.parametrize(("width", "message"), [(1024.7, "not a whole number"), (0, "at least 1")])
def test_xylist_image_size_card_must_be_whole_pixels(tmp_path, width, message):
    """An IMAGEW of 1024.7 names the file and the card, never truncated to 1024."""
    from astropy.io import fits

    cols = [fits.Column(name=n, format="E", array=np.array([1.0, 5.0, 9.0])) for n in "XY"]
    table = fits.BinTableHDU.from_columns(cols)
    table.header["IMAGEW"] = width
    table.header["IMAGEH"] = 768
    p = tmp_path / "c.xyls"
    fits.HDUList([fits.PrimaryHDU(), table]).writeto(p)
    with pytest.raises(InputError, match=rf"c\.xyls: card IMAGEW = .*{message}"):
        read_centroids(p)
    table.header["IMAGEW"] = 1024.0  # a whole number stored as a float is that number
    fits.HDUList([fits.PrimaryHDU(), table]).writeto(p, overwrite=True)
    assert read_centroids(p).image_size == (1024, 768)
