"""Sensor models: optics, detector, exposure and detection thresholds, from TOML presets.

Modules: :mod:`~starsense.sensor.optics` (:class:`Optics`), :mod:`~starsense.sensor.detector`
(:class:`Detector`), :mod:`~starsense.sensor.sensor` (:class:`Sensor`,
:class:`DetectionThresholds`, the pixel geometry) and :mod:`~starsense.sensor.load` (TOML ->
frozen objects, the presets in ``presets/*.toml``).
"""

from starsense.sensor.detector import Detector
from starsense.sensor.load import load_sensor, preset_names, sensor_from_dict
from starsense.sensor.optics import Optics
from starsense.sensor.sensor import DetectionThresholds, Sensor

__all__ = [
    "DetectionThresholds",
    "Detector",
    "Optics",
    "Sensor",
    "load_sensor",
    "preset_names",
    "sensor_from_dict",
]
