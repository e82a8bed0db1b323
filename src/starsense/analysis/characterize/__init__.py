"""A camera measured from its own night-sky frames (``starsense characterize``).

The frames are solved, then the forward model of the solver's refinement is fitted to their
matched stars: the optics (focal length, principal point, distortion), the PSF's width and how
it changes across the field, the photometric zero point, the background and noise (the gain
from the photon transfer where several exposures are given), the hot pixels. Every value comes
with its uncertainty and the frames it was measured on; what the frames cannot tell is kept
from the base sensor, and said.
"""

from starsense.analysis.characterize.camera import camera_sensor, camera_toml, measured_values
from starsense.analysis.characterize.run import Characterisation, characterize
from starsense.analysis.characterize.values import Measured

__all__ = [
    "Characterisation",
    "Measured",
    "camera_sensor",
    "camera_toml",
    "characterize",
    "measured_values",
]
