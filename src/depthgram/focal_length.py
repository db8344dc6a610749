"""The focal length of a camera nobody calibrated, from the scene it sees.

A folder of depth PNGs carries no intrinsics, and a guessed field of view is wrong by a factor of
two for many cameras (YCB-Video's Xtion, registered to its colour camera, has fx = 1067 px at 640
px; a 64-degree guess gives 512). Most of what a depth camera looks at is built: a support (a
table, a floor) and things standing on it or walls rising from it, whose faces meet the support at
right angles. That right angle fixes the focal length.

Why it does: a plane ``n . P = d`` seen through a pinhole with focal length ``f`` and the principal
point at the image centre is linear in inverse depth over centred pixel coordinates,
``1/Z = a u + b v + c``, with ``n`` proportional to ``(a f, b f, c)``. Two planes are
perpendicular when ``f**2 (a1 a2 + b1 b2) + c1 c2 = 0``, so each small planar patch of the frame
that is not on the dominant support votes ``f**2 = -c1 c2 / (a1 a2 + b1 b2)``. Patches at right
angles to the support (box faces, the sides of a mug, a wall) agree on one value; patches at other
angles scatter. The estimate is the densest value of the votes, on a log scale.

It says nothing when the scene cannot tell: a support seen face-on or edge-on (a wall straight
ahead, a corridor's floor along the view: every patch perpendicular to it has ``c`` near 0 and
votes noise), too few votes, or no clear peak. Then the caller keeps its guess and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.ransac import find_planes

__all__ = ["CHECKED_SOURCES", "FocalCheck", "FocalEstimate", "RecordingFocal", "estimate_focal_length"]

#: side of the windows of the local plane fits, at a working width of 320 px or less
_PATCH_PX = 5
#: the working width: wider frames are read on a grid (a focal length scales with the width)
_WORK_WIDTH_PX = 320
#: Intrinsics sources (:data:`depthgram.sources.camera.INTRINSICS_SOURCES`) a person chose, which
#: :class:`FocalCheck` holds against the scene: a device's, a bag's and the simulator's own
#: calibration are the frames' by construction.
CHECKED_SOURCES = ("given", "file", "profile")
#: given intrinsics whose focal length the scene's differs from by more than this factor are wrong:
#: the estimate's own error on the recordings with a calibration is under 15 % (YCB-Video +3 to
#: +10 %, 7-Scenes -14 to -6 %, NVlabs -6 to +6 %, TUM -2 %), a calibration of the wrong camera
#: (the colour camera's, another resolution's) is off by 1.5 to 2
_DISAGREE = 1.4
#: votes are binned between 0.25 and 3 frame widths (fields of view from 19 to 127 degrees)
_F_RANGE = (0.25, 3.0)
_BINS = 100


@dataclass(frozen=True)
class FocalEstimate:
    """A focal length read from the scene.

    Attributes
    ----------
    intrinsics : Intrinsics
        ``fx = fy`` the estimate (px, for the frame as given), the principal point at the image
        centre.
    votes : int
        Planar patches off the support that voted.
    share : float
        Share of the votes within 5 % of the estimate (0..1): how clear the right angle was.
    tilt_deg : float
        Angle between the support's normal and the line of sight under the estimate (degrees).
    """

    intrinsics: Intrinsics
    votes: int
    share: float
    tilt_deg: float


def estimate_focal_length(
    depth_mm: NDArray[np.floating],
    valid: NDArray[np.bool_] | None = None,
    *,
    min_share: float = 0.15,
    min_votes: int = 100,
    tilt_range_deg: tuple[float, float] = (15.0, 75.0),
) -> FocalEstimate | None:
    """Estimate the focal length (px) from the right angles between a support and what rises from it.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Depth (mm), 0 or NaN where there is no reading.
    valid : ndarray of bool, optional
        Pixels with a reading; by default finite and > 0.
    min_share : float
        Smallest share of votes within 5 % of the peak (0..1) for a clear estimate.
    min_votes : int
        Fewest voting patches.
    tilt_range_deg : (float, float)
        The support must be seen at an angle in this range (degrees between its normal and the
        line of sight): face-on and edge-on supports cannot tell the focal length.

    Returns
    -------
    FocalEstimate or None
        None when the scene cannot tell (no oblique support, too few votes, no clear peak).

    Notes
    -----
    The principal point is taken at the image centre; a real one a few percent off moves the
    estimate by about as much.
    """
    depth = np.asarray(depth_mm, np.float32)
    if depth.ndim != 2 or min(depth.shape) < 8 * _PATCH_PX:
        return None
    ok = np.isfinite(depth) & (depth > 0) if valid is None else np.asarray(valid, bool) & (depth > 0)
    h, w = depth.shape
    step = max(1, math.ceil(w / _WORK_WIDTH_PX))
    d, m = depth[::step, ::step], ok[::step, ::step]
    z = np.where(m, d, 0).astype(np.float32)
    planes = find_planes(z, m, max_planes=1)
    if not planes:
        return None
    gh, gw = z.shape
    a, b, c, centre = _patch_planes(z, m)
    # the support's plane in centred coordinates of the grid
    sa, sb, sc = planes[0].coef
    cu, cv = (gw - 1) / 2.0, (gh - 1) / 2.0
    s = (sa, sb, sc + sa * cu + sb * cv)
    off = ~planes[0].inliers[centre[:, 0], centre[:, 1]]
    den = s[0] * a[off] + s[1] * b[off]
    with np.errstate(divide="ignore", invalid="ignore"):
        f2 = -s[2] * c[off] / den
    f_rel = np.sqrt(f2[np.isfinite(f2) & (f2 > 0)]) / gw
    f_rel = f_rel[(f_rel > _F_RANGE[0]) & (f_rel < _F_RANGE[1])]
    if f_rel.size < min_votes:
        return None
    edges = np.linspace(math.log(_F_RANGE[0]), math.log(_F_RANGE[1]), _BINS + 1)
    counts, _ = np.histogram(np.log(f_rel), bins=edges)
    # 5 bins are about +-5 % of the focal length
    smooth = np.convolve(counts, np.ones(5), mode="same")
    k = int(np.argmax(smooth))
    share = float(smooth[k]) / f_rel.size
    f_grid = gw * math.exp(0.5 * (edges[k] + edges[k + 1]))
    f_grid = _refine(f_grid, s, a[off], b[off], c[off])
    f = f_grid * step
    tilt = math.degrees(math.atan2(math.hypot(s[0], s[1]) * f / step, abs(s[2])))
    if share < min_share or not tilt_range_deg[0] <= tilt <= tilt_range_deg[1]:
        return None
    k_px = Intrinsics(f, f, (w - 1) / 2.0, (h - 1) / 2.0)
    return FocalEstimate(k_px, int(f_rel.size), share, tilt)


class RecordingFocal:
    """The focal length of one recording without intrinsics, read once from the first frames that show it.

    A camera's focal length does not change within a recording: the first of up to ``tries``
    frames whose scene shows it (:func:`estimate_focal_length`) sets it for the rest, scaled to
    each frame's size (a resized stream keeps its field of view).
    """

    def __init__(self, tries: int = 5) -> None:
        self.intrinsics: Intrinsics | None = None
        self._tries_left = tries

    def read(
        self, depth_mm: NDArray[np.floating], valid: NDArray[np.bool_]
    ) -> tuple[Intrinsics | None, FocalEstimate | None]:
        """Return the recording's intrinsics for this frame (None while unknown), and this frame's estimate.

        The estimate is not None only for the frame that found the focal length.
        """
        found = None
        if self.intrinsics is None and self._tries_left > 0:
            self._tries_left -= 1
            found = estimate_focal_length(depth_mm, valid)
            if found is not None:
                self.intrinsics = found.intrinsics
        k = self.intrinsics
        h, w = depth_mm.shape
        if k is None or (k.cx, k.cy) == ((w - 1) / 2.0, (h - 1) / 2.0):
            return k, found
        scale = w / (2.0 * k.cx + 1.0)
        return Intrinsics(k.fx * scale, k.fy * scale, (w - 1) / 2.0, (h - 1) / 2.0), found


class FocalCheck:
    """Given intrinsics held against the scene's right angles, once per recording.

    A user's intrinsics can be for another camera or resolution than the frames (a depth image
    registered to the colour camera has the colour camera's focal length; a profile names the
    depth camera's own). Wrong by a factor of 1.6, they turn box faces and a mug's wall into
    supports. The first of up to ``tries`` frames whose scene shows its focal length
    (:func:`estimate_focal_length`) settles the question: within a factor ``disagree`` the given
    intrinsics stand; beyond it the scene's focal length replaces theirs (the principal point
    is kept) for the rest of the recording.

    Attributes
    ----------
    scale : float or None
        The factor applied to the given ``fx`` and ``fy`` once the scene disagreed, else None.
    """

    def __init__(self, tries: int = 5, disagree: float = _DISAGREE) -> None:
        self.scale: float | None = None
        self._tries_left = tries
        self._disagree = disagree

    def read(
        self, depth_mm: NDArray[np.floating], valid: NDArray[np.bool_], given: Intrinsics
    ) -> tuple[Intrinsics, FocalEstimate | None]:
        """Return the intrinsics to use for this frame, and the scene's estimate when it just overruled ``given``."""
        overruled = None
        if self.scale is None and self._tries_left > 0:
            self._tries_left -= 1
            found = estimate_focal_length(depth_mm, valid)
            if found is not None:
                self._tries_left = 0
                ratio = found.intrinsics.fx / math.sqrt(given.fx * given.fy)
                if max(ratio, 1.0 / ratio) > self._disagree:
                    self.scale, overruled = ratio, found
        if self.scale is None:
            return given, overruled
        s = self.scale
        return Intrinsics(given.fx * s, given.fy * s, given.cx, given.cy), overruled


def _refine(
    f: float,
    s: tuple[float, float, float],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    c: NDArray[np.float64],
    rounds: int = 5,
) -> float:
    """Move ``f`` to the median vote of the patches within 10 degrees of a right angle under it.

    The histogram's peak is blurred by patches at other steep angles, which vote near but not at
    the focal length; the median of the near-perpendicular ones, taken again under each new
    estimate, settles on the right angle's own value.
    """
    den = s[0] * a + s[1] * b
    with np.errstate(divide="ignore", invalid="ignore"):
        f2 = -s[2] * c / den
    for _ in range(rounds):
        n1 = np.array([s[0] * f, s[1] * f, s[2]])
        n1 /= np.linalg.norm(n1)
        normals = np.stack([a * f, b * f, c], 1)
        cos = np.abs(normals @ n1) / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)
        near = (cos < math.sin(math.radians(10.0))) & np.isfinite(f2) & (f2 > 0)
        if near.sum() < 20:
            break
        f = float(np.sqrt(np.median(f2[near])))
    return f


def _patch_planes(
    z: NDArray[np.float32], ok: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """Least-squares planes of 1000/Z over centred pixel coordinates in small full windows.

    Returns ``a``, ``b``, ``c`` of the planar windows (those whose fit residual is among the
    frame's lowest) and their centres (row, column).
    """
    gh, gw = z.shape
    k = _PATCH_PX
    one = ok.astype(np.float64)
    q = np.where(ok, 1000.0 / np.where(ok, z, 1.0), 0.0)
    v, u = np.mgrid[0:gh, 0:gw].astype(np.float64)
    u -= (gw - 1) / 2.0
    v -= (gh - 1) / 2.0

    def box(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(cv2.boxFilter(x, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT))

    n = box(one)
    full = n >= k * k  # windows with every reading: no hole, no edge of the frame
    full[:, ::2] = False  # every second window is enough (they overlap)
    rows, cols = np.nonzero(full)
    sums = [box(x)[full] for x in (u * one, v * one, u * u * one, v * v * one, u * v * one, q, u * q, v * q, q * q)]
    su, sv, suu, svv, suv, sq, suq, svq, sqq = sums
    cnt = n[full]
    ata = np.stack([np.stack([suu, suv, su], -1), np.stack([suv, svv, sv], -1), np.stack([su, sv, cnt], -1)], -2)
    atb = np.stack([suq, svq, sq], -1)
    x = np.linalg.solve(ata + np.eye(3) * 1e-9, atb[..., None])[..., 0]
    resid = sqq - 2.0 * np.einsum("ki,ki->k", x, atb) + np.einsum("ki,kij,kj->k", x, ata, x)
    mean_q = sq / cnt
    rel = np.sqrt(np.maximum(resid, 0.0) / cnt) / np.maximum(mean_q, 1e-12)
    # planar: a fit as good as the frame's better half of windows, or within 0.2 % of 1/Z (the
    # noise of a good sensor); depth edges and curved patches fit worse
    planar = rel <= max(0.002, float(np.percentile(rel, 40))) if rel.size else rel > 0
    return x[planar, 0], x[planar, 1], x[planar, 2], np.stack([rows[planar], cols[planar]], 1)
