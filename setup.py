"""Build the compiled kernels (the metadata is in pyproject.toml).

``starsense.detect._clipc`` runs the background mesh's sigma clipping box by box
(src/starsense/detect/_clipc.c); ``starsense.detect._windowc`` tracking's window detection
(src/starsense/detect/_windowc.c); ``starsense.identify._trackc`` tracking's pairing, attitude fit
and covariance (src/starsense/identify/_trackc.c); ``starsense.render._renderc`` the rendering's
stamp sums and fast read-out (src/starsense/render/_renderc.c). They are optional: where one cannot be compiled the package
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
            "starsense.render._renderc",
            ["src/starsense/render/_renderc.c"],
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
        Extension(
            "starsense.identify._trackc",
            ["src/starsense/identify/_trackc.c"],
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
    ]
)
