"""Build the compiled kernels (the metadata is in pyproject.toml).

``starsense.detect._clipc`` runs the background mesh's sigma clipping box by box
(src/starsense/detect/_clipc.c); ``starsense.detect._windowc`` tracking's window detection
(src/starsense/detect/_windowc.c); ``starsense.identify._hashc`` the search and verification of
lost-in-space identification by hashing (src/starsense/identify/_hashc.c). They are optional: where one cannot be compiled the package
installs without it and uses the NumPy implementation of the same algorithm.
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "starsense.detect._clipc",
            ["src/starsense/detect/_clipc.c"],
            optional=True,
        ),
        Extension(
            "starsense.detect._windowc",
            ["src/starsense/detect/_windowc.c"],
            # no fused multiply-add: the kernel's roundings are the NumPy form's
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
        Extension(
            "starsense.identify._hashc",
            ["src/starsense/identify/_hashc.c"],
            # no fused multiply-add: the descriptors' roundings are the NumPy form's
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
    ]
)
