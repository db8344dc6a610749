"""Simulated time-of-flight depth frames with ground truth (paper section 2).

:func:`simulate` renders named scenes (:data:`SCENES`) through a continuous-wave ToF sensor
model (:mod:`depthgram.sensor.tof`): four-phase correlation, shot noise, wrap-around,
optional two-frequency unwrapping, low-amplitude invalid pixels, 8- or 16-bit quantization
and mixed pixels at moving edges. Each :class:`SimFrame` carries the measured
:class:`~depthgram.frame.Frame`, the true depth, the instance map and :class:`TruthObject` s.
"""

from depthgram.sensor import tof
from depthgram.sensor.scenes import SCENES
from depthgram.sensor.simulate import SimFrame, TruthObject, simulate
from depthgram.sensor.tof import ToFConfig

__all__ = ["SCENES", "SimFrame", "ToFConfig", "TruthObject", "simulate", "tof"]
