"""Build the compiled kernels (the metadata is in pyproject.toml).

Each kernel is a C file beside the NumPy implementation of the same algorithm, which stays the
tested reference. They are optional: where one cannot be compiled the package installs without
it and uses the NumPy form.

- ``starsense.detect._clipc``: the background mesh's samples, sigma clipping and noise, box by
  box;
- ``starsense.detect._windowc``: tracking's window detection;
- ``starsense.detect._quickc``: quick extraction's coarse background and its one pass that
  subtracts it and finds the lit pixels;
- ``starsense.detect._framec``: whole-frame detection's background subtraction and threshold
  search, the row and column pattern's line sums, PSF correlation, filtered-noise median and
  labelling;
- ``starsense.identify._hashc``: the search and verification of lost-in-space identification by
  hashing;
- ``starsense.identify._trackc``: tracking's pairing, attitude fit and covariance;
- ``starsense.model._modelc``: the forward model's expected pixels and Jacobian of Gaussian
  stars at rest, and the per-group sums of its normal equations;
- ``starsense.render._renderc``: the renderer's stamp sums and fast read-out noise.
"""

from setuptools import Extension, setup

# no fused multiply-add: the kernels' roundings are the NumPy forms'
NO_FMA = ["-ffp-contract=off"]


def kernel(name: str, *, extra: tuple[str, ...] = ()) -> Extension:
    """The optional extension ``starsense.<name>`` from ``src/starsense/<name>.c``."""
    path = "src/starsense/" + name.replace(".", "/") + ".c"
    return Extension("starsense." + name, [path], extra_compile_args=[*NO_FMA, *extra], optional=True)


setup(
    ext_modules=[
        kernel("detect._clipc"),
        kernel("detect._windowc"),
        kernel("detect._framec", extra=("-O3",)),
        kernel("detect._quickc", extra=("-O3",)),
        kernel("identify._hashc"),
        kernel("identify._trackc"),
        kernel("model._modelc", extra=("-O3",)),
        kernel("render._renderc"),
    ]
)
