"""Build the one compiled kernel (the metadata is in pyproject.toml).

``starsense.detect._clipc`` runs the background mesh's sigma clipping box by box
(src/starsense/detect/_clipc.c). It is optional: where it cannot be compiled the package
installs without it and uses the NumPy implementation of the same algorithm.
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "starsense.detect._clipc",
            ["src/starsense/detect/_clipc.c"],
            optional=True,
        )
    ]
)
