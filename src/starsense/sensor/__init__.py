"""Sensor models: optics, detector, exposure and detection thresholds, from TOML presets."""

from starsense.sensor.config import (
    DetectionThresholds,
    Detector,
    Optics,
    Sensor,
    load_sensor,
    preset_names,
    sensor_from_dict,
)

__all__ = [
    "DetectionThresholds",
    "Detector",
    "Optics",
    "Sensor",
    "load_sensor",
    "preset_names",
    "sensor_from_dict",
]
