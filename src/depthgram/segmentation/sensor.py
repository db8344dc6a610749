"""The sensor noise model under its former module name (kept so that existing imports work).

The model lives in :mod:`depthgram.segmentation.noise_model`; the ToF simulator is the
package :mod:`depthgram.sensor`.
"""

from __future__ import annotations

from depthgram.segmentation.noise_model import PROFILES, SensorModel, estimate_sensor, sensor_model

__all__ = ["PROFILES", "SensorModel", "estimate_sensor", "sensor_model"]
