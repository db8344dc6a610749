"""Simulated time-of-flight depth frames with ground truth (paper section 2).

:func:`simulate` renders named scenes (:data:`SCENES`) through a continuous-wave ToF sensor
model (:mod:`depthgram.sensor.tof`): four-phase correlation, shot noise, wrap-around,
optional two-frequency unwrapping, low-amplitude invalid pixels, 8- or 16-bit quantization
and mixed pixels at moving edges; or (``sensor="structured-light"``) through a Kinect v1 /
Xtion-like structured-light model (:mod:`depthgram.sensor.structured`): 1/8 px disparity
quantisation, disparity noise, projector shadows and registration holes. Each
:class:`SimFrame` carries the measured :class:`~depthgram.frame.Frame`, the true depth, the
instance map and :class:`TruthObject` s.
"""

from depthgram.sensor import structured, tof
from depthgram.sensor.scenes import SCENES
from depthgram.sensor.simulate import SENSORS, SimFrame, TruthObject, simulate
from depthgram.sensor.structured import StructuredLightConfig
from depthgram.sensor.tof import ToFConfig

__all__ = [
    "SCENES",
    "SENSORS",
    "SimFrame",
    "StructuredLightConfig",
    "ToFConfig",
    "TruthObject",
    "simulate",
    "structured",
    "tof",
]
