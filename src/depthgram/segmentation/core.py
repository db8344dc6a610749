"""The segmentation entry point: depth image in, objects with attributes out."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Frame, Intrinsics, check_array_units
from depthgram.segmentation._kernels.feet import take_back
from depthgram.segmentation._kernels.surfaces import restore_unclaimed
from depthgram.segmentation.attributes import ObjectSpec, Stats, attribute_rows, make_objects, objects_from_rows
from depthgram.segmentation.coarse import grid_frame, grid_step, to_full_resolution
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.contacts import front_faces, planes_in_pixels, side_faces
from depthgram.segmentation.coplanar import class_window, coplanar_groups
from depthgram.segmentation.creases import crease_scale_px, crease_span_px, crease_state, inverse_depth
from depthgram.segmentation.feet import feet_reach, give_feet
from depthgram.segmentation.histogram import Bands, bin_index, depth_bands, log_bin_counts
from depthgram.segmentation.label import label_bands_stats, label_stats_fused, relabel
from depthgram.segmentation.label.stats import COUNT, KEY, N_SUMS, SUM_X, SUM_XZ, SUM_Y, SUM_YZ, SUM_Z, add_rows
from depthgram.segmentation.noise_model import SensorModel, estimate_sensor, sensor_model
from depthgram.segmentation.objects import Histogram, SceneObject, Segmentation
from depthgram.segmentation.openings import merge_openings
from depthgram.segmentation.order_stats import median_inplace
from depthgram.segmentation.orientation import (
    FACING,
    HORIZONTAL,
    VERTICAL,
    default_intrinsics,
    load_opencv_routes,
    orientation_classes,
    upsample_classes,
)
from depthgram.segmentation.paper_slices import paper_slices
from depthgram.segmentation.plane_sums import plane_sums_in_boxes, planes_from_sums, shares_beneath
from depthgram.segmentation.raised import raised_pieces
from depthgram.segmentation.ransac import find_planes, plane_normal
from depthgram.segmentation.ransac import warm_up as warm_up_ransac
from depthgram.segmentation.region import region_grow
from depthgram.segmentation.slices import (
    add_through,
    compound_parts,
    drop_classes,
    support_kind,
    support_pieces_lazy,
)
from depthgram.segmentation.slices import warm_up as warm_up_slices
from depthgram.segmentation.supports import SupportMap, label_supports
from depthgram.segmentation.surfaces import facing_halves, surfaces_kept
from depthgram.segmentation.validate import check_depth_far

__all__ = ["load_rare_kernels", "segment", "warm_up"]

#: The defaults, built once: validating a config on every call is a visible share of a small frame.
_DEFAULTS = SegmentConfig()
#: How far below the plane (a share of a piece's height) a horizontal support may lie just beyond
#: a piece cut from it (``raised_pieces``' ``ring_trough``): 0.4-0.9 beside three of NVlabs' stereo
#: streaks, at most 0.24 beside 275 of 7-Scenes' 276 magazines (design notes, 2 December 2026,
#: issue 28 item 5). Facing supports (the default's) are held to neither this nor ``_OUTLINE``.
_TROUGH = 0.3
#: Most a piece cut from a horizontal support may have of outline over the root of its area
#: (``raised_pieces``' ``ring_outline``): NVlabs' stereo mosaics 17.8 and 22.5, 7-Scenes'
#: magazines 10.7 at most, the simulator's things 7.1.
_OUTLINE = 14.0
#: Share of the frame a horizontal support must hold for the default to cut it: the largest one's
#: share is 0.20 on 7-Scenes' median frame and 0.28 at its 90th percentile, 0.35-0.69 on
#: NVlabs' and OSD's tabletops, 0.80 on the simulator's arm_45 (design notes, 3 December 2026).
_SCENE_SHARE = 1.0 / 3.0


def segment(
    depth_mm: NDArray[np.floating] | Frame,
    *,
    valid: NDArray[np.bool_] | None = None,
    intrinsics: Intrinsics | None = None,
    config: SegmentConfig | None = None,
    sensor: SensorModel | str | None = None,
    **overrides: Any,
) -> Segmentation:
    """Segment one depth image into salient objects (paper, section 3).

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W), or Frame
        Depth along the optical axis (mm); 0 or NaN where there is no reading. A
        :class:`~depthgram.frame.Frame` (from :func:`depthgram.read`) brings its own validity
        mask and intrinsics, used unless ``valid`` / ``intrinsics`` are given. A bare array
        whose values cannot be millimetres (floats all under 20: metres; a median beyond 8 m)
        gives a :class:`~depthgram.frame.UnitsWarning`.
    valid : ndarray of bool, optional
        Pixels with a reading; by default finite and > 0.
    intrinsics : Intrinsics, optional
        Camera intrinsics (px). Fill ``centroid_mm`` and ``area_mm2``; the ``slices`` method
        uses them for surface orientation (a 64 degree field of view is assumed without).
    config : SegmentConfig, optional
        Parameters; defaults when omitted.
    sensor : SensorModel or str, optional
        The camera's depth step and noise, for the ``surfaces`` method: a model, or a profile
        name or ``auto`` as the config's ``sensor`` takes; by default the config's (estimated
        from this frame when ``auto``). A stream passes the
        model it estimated once (:class:`depthgram.pipeline.Pipeline` does) instead of paying
        for an estimate on every frame.
    **overrides
        Fields of :class:`SegmentConfig` to change, e.g. ``method="threshold"``.

    Returns
    -------
    Segmentation
        ``labels`` (int32, 0 = background, invalid or too small), ``objects`` in id order,
        ``histogram`` (global histogram, peaks and trailing cuts), ``method``, ``bands_mm``
        (K x 2 band limits, mm) and for ``slices`` the orientation ``classes``.

    Raises
    ------
    InputError
        For a non-2-D or non-numeric image, a mask of another shape, or absurd options.

    Notes
    -----
    ``threshold``: the global depth histogram's peaks (``scipy.signal.find_peaks`` with a
    prominence floor) each give a depth band; every band is split into connected components
    (holes of up to ``fill_holes_px`` bridged), small ones dropped. ``slices``: the same for
    pixels facing the sensor, while horizontal surfaces and walls become compound objects
    (``floor``, ``ceiling``, ``wall``, ``compound``) made of slice ``part``s. ``region``: region
    growing, see :func:`depthgram.segmentation.region_grow`.

    Why the defaults read the paper as they do (the 10 % rule, gap pixels, depth-dependent
    bins) is in ``docs/design-notes.md``; accuracy and speed per method are printed by
    ``depthgram bench`` and collected in ``docs/performance.md``.
    """
    if isinstance(depth_mm, Frame):
        valid = depth_mm.valid if valid is None else valid
        intrinsics = depth_mm.intrinsics if intrinsics is None else intrinsics
        depth_mm = depth_mm.depth
    elif valid is None:
        # a caller's own array (the pipeline and the sources pass a mask and were checked when read)
        check_array_units(depth_mm, "segment")
    if isinstance(sensor, str):
        overrides["sensor"] = sensor
        sensor = None
    cfg = (config or _DEFAULTS).with_overrides(**overrides)
    depth, ok, n_far = check_depth_far(depth_mm, valid, cfg.far_mm)
    seg = _segment(depth, ok, intrinsics, cfg, sensor)
    return replace(seg, beyond_far_px=n_far) if n_far else seg


def warm_up() -> None:
    """Load (on a fresh install: compile) the compiled kernels that only some frames reach.

    The first frame of a stream loads the kernels its own branches take; one taking a branch
    the first frames did not (a support labelled again after pixels near its plane joined it,
    coplanar pieces joined, small pieces dropped, the statistics after merged openings, a face
    folded into its support, the first supports) loaded or compiled its kernels in the middle
    of the stream (470 ms on a fresh install). A real-time caller runs this before the stream,
    after a first frame (``Pipeline.warm_up``). ``load_rare_kernels`` is its former name.
    """
    z = np.full((2, 2), 1000.0, np.float32)
    ok = np.ones((2, 2), np.bool_)
    classes = np.full((2, 2), HORIZONTAL, np.int8)
    cam = default_intrinsics(z.shape)
    # a class labelled alone (its near pixels joined): labeller state, labeller, tables, planes
    win = class_window(np.array([[2, 2, -1, -1], [0, 0, 1, 1]], np.int64), np.ones(2), z.shape, min_px=1)
    support_pieces_lazy(z, ok, classes, HORIZONTAL, cam, jump_rel=0.05, bridge=2, min_fit_px=1, window=win)
    # small or flat pieces dropped back to the facing class
    drop_classes(
        np.zeros((2, 2), np.int32), np.zeros(1, np.int32), 0, classes.copy(), FACING, np.zeros((0, 4), np.int64)
    )
    # coplanar pieces joined: their rows added
    warm_up_slices()
    # merged openings: the statistics of the joined surfaces
    label_stats_fused(np.zeros((2, 2), np.int32), 0, z, np.zeros((2, 2), np.float32))
    # a front or side face of a support: the contacts, and its row added to the support's
    front_faces(
        np.array([[2, 2], [1, 1]], np.int32), z, np.ones(2), np.array([2], np.int32), jump_rel=0.05,
        boxes=np.array([[0, 0, 1, 0]], np.int64), n_ids=3,
    )  # fmt: skip
    add_rows(np.zeros((3, N_SUMS)), np.zeros((3, 4), np.int64), np.array([1], np.intp), np.array([2], np.intp))
    # an object's foot given back by a horizontal support (a frame without one never calls it)
    give_feet(
        np.array([[1, 2], [2, 2]], np.int32), z, ok, [2], 1, sensor_model("tof"), np.ones((3, N_SUMS)),
        np.array([[0, 0, 1, 1], [0, 0, 0, 0], [0, 0, 1, 1]], np.int64), reach=1, min_px=1,
    )  # fmt: skip
    # a small piece no surface took back, kept to be judged with its foot (surfaces_kept)
    restore_unclaimed(np.zeros(2, np.int32), np.ones(2, np.int32), np.zeros(2, np.int64), np.zeros(2, np.int64), 1)
    take_back(
        np.ones((2, 2), np.int32), np.ones((2, 2), np.int32), (0, 0), np.ones(2, np.bool_), z, np.ones((2, N_SUMS))
    )
    # ids renumbered after a fold; the slice parts of supports (a frame without any has none)
    relabel(np.zeros((2, 2), np.int32), np.zeros(1, np.int32))
    compound_parts(
        np.ones((2, 2), np.int32), z, [(1, (0, 0, 2, 2), True)], step_of=lambda extent: 1,
        depth_label=lambda depths: np.zeros(depths.shape, np.intp), intrinsics=cam, first_id=2,
    )  # fmt: skip
    # a plane search that finds a plane (its pieces' percentiles), planes from their sums, and
    # large pieces compared for one plane
    find_planes(z, ok, min_area=0.0, min_spread=0.0)
    planes_from_sums(np.zeros((1, 9), np.float64))
    coplanar_groups(np.eye(3), np.ones(3), np.ones(3))
    # the pixels of the planes found (a 2 x 2 frame finds none; 7-Scenes on the grid of a
    # 640 px frame first found one at frame 5: 367 ms on a fresh install)
    warm_up_ransac()
    # the window sums of a frame whose values span too many octaves for float64 (OpenCV's)
    load_opencv_routes()


#: The former name of :func:`warm_up`.
load_rare_kernels = warm_up


def _segment(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    cfg: SegmentConfig,
    sensor: SensorModel | None,
) -> Segmentation:
    if cfg.method == "region":
        return region_grow(depth, valid=ok, intrinsics=intrinsics, config=cfg)
    if not ok.any():
        empty = Histogram(np.zeros(1), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
        return Segmentation(np.zeros(depth.shape, np.int32), (), empty, cfg.method, bands_mm=np.zeros((0, 2)))
    if cfg.method == "threshold":
        return _threshold(depth, ok, intrinsics, cfg)
    if cfg.method == "paper":
        return paper_slices(depth, ok, intrinsics, cfg)
    step = grid_step(depth.shape[1], cfg.work_width_px) if cfg.method == "surfaces" else 1
    if step == 1:
        seg = _slices(depth, ok, intrinsics, cfg, sensor)
        objects = objects_from_rows(seg.specs, seg.rows, seg.boxes, depth.size, metric=intrinsics is not None)
        return seg.segmentation(seg.labels, seg.classes, objects, cfg)
    # one sensor model for the grid and the refinement, estimated on every pixel
    sensor = sensor or frame_sensor(depth, ok, cfg)
    cam = intrinsics or default_intrinsics(depth.shape)
    gd, gok, gcam = grid_frame(depth, ok, cam, step)
    gcfg = cfg.with_overrides(min_area_px=max(1, cfg.min_area_px // (step * step)))
    # the objects are built once, at full resolution; the parts are the grid's, in the frame's pixels
    grid = _slices(gd, gok, gcam if intrinsics is not None else None, gcfg, sensor, (step, *depth.shape[::-1]))
    t0, t2, slope = _join_rule(sensor, cfg, cam.fx)
    labels, classes, objects = to_full_resolution(
        grid.labels, grid.classes, grid.specs, gd, depth, ok, intrinsics, step, tol_0=t0, tol_2=t2, slope_per_px=slope
    )
    return grid.segmentation(labels, classes, objects, cfg)


def _join_rule(sensor: SensorModel, cfg: SegmentConfig, focal_px: float) -> tuple[float, float, float]:
    """Return when two readings lie on one surface: ``(tol_0, tol_2, slope_per_px)``.

    Depths ``z_a``, ``z_b`` a distance ``d`` px apart join when ``|z_a - z_b| <= tol_0 + tol_2 z**2
    + d slope_per_px z``: the sensor's resolution times ``join_resolutions``, plus what a surface
    at ``max_slope_deg`` moves over ``d`` px at focal length ``focal_px``. The surface labeller
    and the grid's refinement use the same rule.
    """
    t0, t2 = sensor.tolerance(cfg.join_resolutions)
    return t0, t2, math.tan(math.radians(cfg.max_slope_deg)) / focal_px


def frame_sensor(depth: NDArray[np.float32], ok: NDArray[np.bool_], cfg: SegmentConfig) -> SensorModel:
    """Return the sensor model of ``cfg.sensor``: a named profile, or estimated from this frame."""
    if cfg.sensor == "auto":
        return estimate_sensor(depth, ok)
    return sensor_model(cfg.sensor)


def _facing_objects(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    include: NDArray[np.bool_] | None,
    cfg: SegmentConfig,
) -> tuple[NDArray[np.int32], Bands, NDArray[np.float64], NDArray[np.int64]]:
    """Facing objects as depth bands: label map, bands, statistics table (``KEY``: the band) and boxes."""
    # the bands come from the histogram; labelling reads each pixel's band through the
    # bin -> band table and gathers the statistics in the same pass (no band image, no
    # separate statistics pass, no relabelling pass for the small components)
    hist_mask = ok if include is None else ok & include
    bins, edges, counts = bin_index(depth, hist_mask, cfg, zero_outside=include is None)
    bands = depth_bands(counts, edges, cfg)
    labels, _, sums, boxes = label_bands_stats(
        bins, bands.lut, ok, include, depth, bridge=cfg.fill_holes_px, min_px=cfg.min_pixels(depth.size)
    )
    return labels, bands, sums, boxes


def _surface_objects(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    include: NDArray[np.bool_],
    cam: Intrinsics,
    cfg: SegmentConfig,
    sensor: SensorModel,
    inverse: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.int32], Bands, NDArray[np.float64], NDArray[np.int64]]:
    """Facing objects as depth-continuous surfaces (:mod:`depthgram.segmentation.surfaces`).

    ``inverse``: the frame's 1000 / Z and readings, when the orientation field took them.
    The same outputs as :func:`_facing_objects` (the objects are built with the supports'); the
    histogram's bands give each object its depth label only. Its bins follow the sensor:
    geometric, and at the far end of the frame three resolutions wide, so that a structured-light
    camera's depth steps (which grow with the square of depth) never make a comb of one-bin peaks.
    """
    # the histogram only names depth labels here: every 2nd row and column give the same bands
    # at a quarter of the cost; its far end is np.percentile's value, compiled (a numpy call
    # costs more than the selection here)
    facing, d2, m2, far, span = facing_halves(depth, ok, include, float(cfg.ref_depth_mm))
    bin_far = max(cfg.bin_mm * far / cfg.ref_depth_mm, 3.0 * float(sensor.resolution(far)))
    # within the config's own bounds, so that a frame of absurd depths is binned, not refused here
    ref = min(max(far, 1.0), 1e6)
    edges, counts = log_bin_counts(d2, m2, min(max(bin_far, 0.01), 10_000.0), ref, span)
    bands = depth_bands(counts, edges, cfg)
    # the span follows the sensor's correlation window unless the config sets it
    r = crease_span_px(depth.shape[1], sensor, cfg.crease_span_fraction)
    # the labeller's state with the concave creases blocking, in one call
    state = crease_state(
        depth, ok, facing, sensor, scale_px=r, min_angle_deg=cfg.crease_deg, focal_px=cam.fx, inverse=inverse
    )
    t0, t2, slope = _join_rule(sensor, cfg, cam.fx)
    # crease pixels and pieces too small to keep (the inside of a cup cut off by the crease of
    # its bottom) go to the surface they continue, then what is still too small is dropped
    labels, n, sums, boxes = surfaces_kept(
        depth,
        state,
        facing,
        tol_0=t0,
        tol_2=t2,
        slope_per_px=slope,
        bridge_px=cfg.fill_holes_px,
        min_px=cfg.min_pixels(depth.size),
        max_px=4 * r + 1,
        seed_px=_seed_px(cfg.min_pixels(depth.size)),
        # min_area was set with the base span's crease bands: a wider span's extra width is
        # given back to a small piece before it is judged
        band_px=r - crease_scale_px(depth.shape[1]),
    )
    mean = sums[:, SUM_Z] / np.maximum(sums[:, COUNT], 1.0)
    # np.median's value, compiled (the numpy call cost more than the selection here)
    step = t0 + t2 * median_inplace(mean[1:].copy()) ** 2 if n else t0
    joined = merge_openings(labels, depth, boxes, mean, focal_px=cam.fx, ring_px=2 * r, jump_mm=4.0 * step)
    if joined is not None:
        labels = relabel(labels, joined)
        n = int(joined.max())
        sums, boxes = label_stats_fused(labels, n, depth, np.zeros(depth.shape, np.float32))
        mean = sums[:, SUM_Z] / np.maximum(sums[:, COUNT], 1.0)
    sums[:, KEY] = bands.depth_label(mean)
    return labels, bands, sums, boxes


def _threshold(
    depth: NDArray[np.float32], ok: NDArray[np.bool_], intrinsics: Intrinsics | None, cfg: SegmentConfig
) -> Segmentation:
    labels, bands, sums, boxes = _facing_objects(depth, ok, None, cfg)
    stats = Stats.from_sums(sums, boxes, metric=intrinsics is not None)
    objects = make_objects(labels, stats, depth_labels=sums[:, KEY].astype(np.int64), intrinsics=intrinsics)
    return Segmentation(labels, tuple(objects), bands.histogram, "threshold", bands_mm=bands.limits_mm())


@dataclass
class _Sliced:
    """A segmentation with supports before its objects are built (:func:`_slices`)."""

    labels: NDArray[np.int32]
    classes: NDArray[np.int8]
    bands: Bands
    specs: list[ObjectSpec]  # the objects 1..n in id order
    rows: list[list[float]]  # attribute_rows of ids 1..n on this label map
    boxes: list[list[int]]  # inclusive boxes of ids 0..n

    def segmentation(
        self, labels: NDArray[np.int32], classes: NDArray[np.int8], objects: list[SceneObject], cfg: SegmentConfig
    ) -> Segmentation:
        """Return the segmentation of these bands with the given label map, classes and objects."""
        bands = self.bands
        return Segmentation(
            labels, tuple(objects), bands.histogram, cfg.method, bands_mm=bands.limits_mm(), classes=classes
        )


def _slices(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    cfg: SegmentConfig,
    sensor: SensorModel | None = None,
    part_scale: tuple[int, int, int] | None = None,
) -> _Sliced:
    """Segment with supports (``slices`` and ``surfaces``), in five named steps.

    1. :func:`_pixel_classes`: each pixel facing the sensor, on a horizontal or on a vertical
       surface (orientation field and dominant planes).
    2. :func:`_support_class` per wanted direction: the supports (floor, table tops, walls).
    3. The objects among the facing pixels: :func:`_surface_objects` or :func:`_facing_objects`.
    4. :func:`_stack_supports` and :func:`_fold_faces`: supports join the label map after the
       objects (flat things lying on them cut out, :func:`_cut_raised`, and each object's foot
       given back, :func:`_give_feet`), and a box's front or side face joins the support it
       belongs to.
    5. :func:`_compound_objects`: ids 1..n again, each support's kind and its slice parts.

    The objects are described, not built: the caller builds them from these statistics or,
    for a frame's sampling grid, from the full-resolution ones (``part_scale``: ``(step,
    width, height)`` of that frame, in whose pixels the parts are given).
    """
    cam = intrinsics or default_intrinsics(depth.shape)
    classes, wanted, inverse = _pixel_classes(depth, ok, cam, cfg)
    min_px = cfg.min_pixels(depth.size)
    # supports first: a piece of surface too small to matter goes back to the facing pixels
    support_maps = label_supports(depth, ok, classes, wanted, cam, cfg, min_px)
    facing = classes == FACING
    if cfg.method == "surfaces":
        sensor = sensor or frame_sensor(depth, ok, cfg)
        labels, bands, fsums, fboxes = _surface_objects(depth, ok, facing, cam, cfg, sensor, inverse=inverse)
    else:
        labels, bands, fsums, fboxes = _facing_objects(depth, ok, facing, cfg)
    stack = _stack_supports(labels, fsums, fboxes, support_maps, cam)
    if cfg.method == "surfaces" and cfg.raised_sigmas > 0 and sensor is not None:
        stack = _cut_raised(labels, depth, ok, classes, stack, sensor, bands, cam, cfg, min_px)
    if cfg.method == "surfaces" and sensor is not None:
        stack = _give_feet(labels, depth, ok, stack, sensor, cam, cfg, min_px)
    below, beneath, planes = _below_camera(labels, depth, cam, stack)
    fronts = _fold_faces(labels, depth, stack, below, planes, cfg)
    labels, specs, rows, boxes = _compound_objects(
        labels, depth, stack, fronts, below, beneath, bands, intrinsics, cam, cfg, part_scale
    )
    return _Sliced(labels, classes, bands, specs, rows, boxes)


def _pixel_classes(
    depth: NDArray[np.float32], ok: NDArray[np.bool_], cam: Intrinsics, cfg: SegmentConfig
) -> tuple[NDArray[np.int8], list[int], NDArray[np.float32] | None]:
    """Return each pixel's orientation class, the support classes the config slices, and 1/Z.

    Classes of directions the config does not slice are turned back into facing pixels. The
    last item is the frame's 1000 / Z and readings (:func:`_orientation`), or None.
    """
    classes, inverse = _orientation(depth, ok, cam, cfg)
    if cfg.support_planes and cfg.max_planes:
        _add_support_planes(depth, ok, classes, cam, cfg)
    wanted = []
    if cfg.slice_directions in ("both", "horizontal"):
        wanted.append(HORIZONTAL)
    if cfg.slice_directions in ("both", "vertical"):
        wanted.append(VERTICAL)
    for cls in (HORIZONTAL, VERTICAL):
        if cls not in wanted:
            classes[classes == cls] = FACING
    return classes, wanted, inverse


@dataclass
class _Stack:
    """Statistics of every id, facing objects first and then supports, stacked.

    Later steps add rows instead of taking them again from the label map; the objects are
    built once, at the end (:func:`_compound_objects`), from these rows.
    """

    sums: NDArray[np.float64]  # (next_id, N_SUMS): the statistics table's sums per id
    boxes: NDArray[np.int64]  # (next_id, 4) inclusive boxes per id
    keys: NDArray[np.int64]  # (first_support,) each facing object's depth label
    first_support: int  # id of the first support
    next_id: int  # one past the last id
    supports: list[tuple[int, int]]  # (orientation class, id) per support with pixels
    #: (next_id - 1, 8) the attributes of ids 1.. (attributes.attribute_rows), before faces fold
    attrs: NDArray[np.float64]
    #: objects cut out of the supports (:func:`_cut_raised`): ids after the supports'
    raised: list[int] = field(default_factory=list)


def _stack_supports(
    labels: NDArray[np.int32],
    fsums: NDArray[np.float64],
    fboxes: NDArray[np.int64],
    support_maps: list[SupportMap],
    cam: Intrinsics,
) -> _Stack:
    """Add the supports' labels after the facing objects' (in place) and stack their statistics."""
    next_id = fsums.shape[0]
    first_support = next_id
    all_sums = [fsums[:, :N_SUMS]]
    all_boxes = [fboxes]
    supports: list[tuple[int, int]] = []
    # one table per label map (the classes labelled together share one): map value -> id
    luts: dict[int, tuple[NDArray[np.int32], NDArray[np.int32], list[NDArray[np.int64]]]] = {}
    for sm in support_maps:
        if sm.n == 0:
            continue
        _, lut, in_boxes = luts.setdefault(id(sm.labels), (sm.labels, np.zeros(sm.size, np.int32), []))
        in_boxes.append(sm.boxes[1:])
        kept = sm.through[1:]
        lut[sm.base + 1 : sm.base + kept.size + 1] = np.where(kept > 0, kept + np.int32(next_id - 1), 0)
        supports += [(sm.cls, i) for i in range(next_id, next_id + sm.n)]
        all_sums.append(sm.sums[1:, :N_SUMS])
        all_boxes.append(sm.boxes[1:])
        next_id += sm.n
    for lab, lut, in_boxes in luts.values():
        add_through(labels, lab, lut, in_boxes[0] if len(in_boxes) == 1 else np.concatenate(in_boxes))
    total = np.concatenate(all_sums) if len(all_sums) > 1 else all_sums[0].copy()
    total_boxes = np.concatenate(all_boxes) if len(all_boxes) > 1 else all_boxes[0].copy()
    attrs = attribute_rows(total, cam)
    # a support without pixels is no object (make_objects leaves such rows out)
    supports = [(c, i) for c, i in supports if attrs[i - 1, 0] > 0]
    keys = fsums[:, KEY].astype(np.int64)
    return _Stack(total, total_boxes, keys, first_support, next_id, supports, attrs)


def _cut_raised(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    classes: NDArray[np.int8],
    stack: _Stack,
    sensor: SensorModel,
    bands: Bands,
    cam: Intrinsics,
    cfg: SegmentConfig,
    min_px: int,
) -> _Stack:
    """Cut what lies on each support above its noise into objects of their own (in place).

    The supports are the facing objects as large as a dominant plane (``cfg.plane_min_area`` of
    the frame), and with ``cfg.raised_supports == "all"`` the horizontal ones.

    The pieces (:func:`depthgram.segmentation.raised.raised_pieces`) take ids after the last
    support's; their statistics come out of their support's row, which stays additive.
    """
    if cfg.raised_supports == "all":
        tops = [i for c, i in stack.supports if c == HORIZONTAL]
    else:
        # a horizontal support holding a third of the view is the scene itself (the table an
        # arm camera looks at 45 degrees down, the floor before a chest camera): what lies
        # there is what the user came for; a kitchen's counters seen in passing are not cut
        tops = [i for c, i in stack.supports if c == HORIZONTAL and stack.attrs[i - 1, 0] >= _SCENE_SHARE * depth.size]
    # a plane facing the camera and as large as a dominant plane is a support too: a table seen
    # from above (an arm camera), where flat things lying on it are the whole scene
    broad = (np.flatnonzero(stack.attrs[: stack.first_support - 1, 0] >= cfg.plane_min_area * depth.size) + 1).tolist()
    if not tops and not broad:
        return stack
    found: list[tuple[NDArray[np.int32], list[int], tuple[int, int, int, int]]] = []
    for ids, cls in ((tops, HORIZONTAL), (broad, FACING)):
        if ids:
            got = raised_pieces(
                labels, depth, ok, classes, cls, ids, stack.boxes[ids], sensor, min_px=min_px,
                k_sigma=cfg.raised_sigmas, ring_trough=_TROUGH if cls == HORIZONTAL else math.inf,
                ring_outline=_OUTLINE if cls == HORIZONTAL else math.inf,
                # a structured-light camera's depth bends most toward the frame's corners: a
                # piece of a table seen at an angle with a third of its ring beyond the frame,
                # not seen, is not told from that bend
                refuse_corners=cls == HORIZONTAL,
            )  # fmt: skip
            if got[1]:
                found.append(got)  # most supports: nothing cut, no frame-sized work
    if not found:
        return stack
    # only the box holding every piece is read: the pieces' ids after the last support's
    x0, y0 = min(b[0] for _, _, b in found), min(b[1] for _, _, b in found)
    x1, y1 = max(b[2] for _, _, b in found), max(b[3] for _, _, b in found)
    here = (slice(y0, y1), slice(x0, x1))
    of_support: list[int] = list(found[0][1])
    # one class cut (most frames): its map already numbers the pieces 1..k
    pieces = found[0][0][here]
    if len(found) > 1:
        pieces = pieces.copy()
        for map_, of, _ in found[1:]:
            part = map_[here]
            np.add(part, np.int32(len(of_support)), out=pieces, where=part > 0)
            of_support += of
    k = len(of_support)
    sums, boxes = label_stats_fused(pieces, k, depth[here], np.zeros(pieces.shape, np.float32))
    # the box's sums and boxes in the frame's columns and rows
    sums[:, SUM_X] += x0 * sums[:, COUNT]
    sums[:, SUM_XZ] += x0 * sums[:, SUM_Z]
    sums[:, SUM_Y] += y0 * sums[:, COUNT]
    sums[:, SUM_YZ] += y0 * sums[:, SUM_Z]
    boxes[1:] += np.array([x0, y0, x0, y0], np.int64)
    new = np.arange(stack.next_id, stack.next_id + k)
    # written through the box's view where a piece is: no frame-sized index arrays
    np.add(pieces, np.int32(stack.next_id - 1), out=labels[here], where=pieces > 0)
    total = np.concatenate([stack.sums, sums[1:, :N_SUMS]])
    for j, sid in enumerate(of_support, start=1):
        total[sid] -= sums[j, :N_SUMS]
    mean = sums[1:, SUM_Z] / np.maximum(sums[1:, COUNT], 1.0)
    keys = np.concatenate([stack.keys, np.zeros(new[0] - stack.keys.size, np.int64), bands.depth_label(mean)])
    return replace(
        stack,
        sums=total,
        boxes=np.concatenate([stack.boxes, boxes[1:]]),
        keys=keys.astype(np.int64),
        next_id=stack.next_id + k,
        attrs=attribute_rows(total, cam),
        raised=new.tolist(),
    )


def _give_feet(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    stack: _Stack,
    sensor: SensorModel,
    cam: Intrinsics,
    cfg: SegmentConfig,
    min_px: int,
) -> _Stack:
    """Give the facing objects the feet the horizontal supports took (:mod:`~depthgram.segmentation.feet`)."""
    tops = [i for c, i in stack.supports if c == HORIZONTAL]
    reach = feet_reach(cfg.normal_window_px)
    n = stack.first_support - 1
    # the facing pieces under min_px that no surface took back (surfaces_kept): a thing so small
    # that its foot is a large share of it, judged with its foot; one copy of the box around
    # them all tells their feet from their own readings afterwards
    count = stack.sums[1 : n + 1, COUNT]
    small = np.flatnonzero((count > 0) & (count < min_px)) + 1
    if small.size:
        b = stack.boxes[small]
        h, w = labels.shape
        y0, x0 = max(0, int(b[:, 1].min()) - reach), max(0, int(b[:, 0].min()) - reach)
        around = (slice(y0, min(h, int(b[:, 3].max()) + reach + 1)), slice(x0, min(w, int(b[:, 2].max()) + reach + 1)))
        before = labels[around].copy()
        own = count[small - 1].copy()
    moved = give_feet(
        labels, depth, ok, tops, n, sensor, stack.sums, stack.boxes, reach=reach, min_px=min(min_px, _seed_px(min_px))
    )  # fmt: skip
    if small.size:
        # a piece whose foot outweighs it is the support's own bend around a speck, not a thing
        total = stack.sums[small, COUNT]
        dropped = np.zeros(n + 1, np.bool_)
        dropped[small[(total < min_px) | (total > 2.0 * own)]] = True
        if dropped.any():
            # still too small: its readings are no object's, its foot goes back to its support
            moved += take_back(labels, before, (y0, x0), dropped, depth, stack.sums)
    return replace(stack, attrs=attribute_rows(stack.sums, cam)) if moved else stack


def _seed_px(min_px: int) -> int:
    """Smallest facing piece kept for its support to judge (px), a quarter of ``min_px``.

    Specks and edge fragments are smaller and cost the feet nothing; what is kept was the
    same on the labelled recordings from a half to an eighth (docs/design-notes.md).
    """
    return max(1, min_px // 4)


def _fold_faces(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    stack: _Stack,
    below: dict[int, float],
    planes: dict[int, tuple[float, float, float]],
    cfg: SegmentConfig,
) -> dict[int, int]:
    """Return ``{face id: support id}`` and add each face's statistics to its support's (in place).

    A front face stands below a support seen from above (a table's front under its top); a
    side face is a small vertical support beside a facing object (a box at an angle); beside a
    facing object already folded into a support, the side folds into that support too (a box
    seen from above: top, the strip at its edge the orientation field calls horizontal, side),
    so the returned ids include such supports. ``planes`` are the horizontal supports'
    (:func:`_below_camera`): a front face lies behind its support's plane continued.
    """
    n_facing = stack.first_support - 1
    boxes = stack.boxes
    # the supports' boxes (inclusive) hold all their pixels: the contacts are counted inside them
    tops = [i for c, i in stack.supports if c == HORIZONTAL and below[i] > 0]
    widths = np.zeros(n_facing + 1, np.float64)
    widths[1:] = boxes[1 : n_facing + 1, 2] - boxes[1 : n_facing + 1, 0] + 1
    fronts = front_faces(
        labels,
        depth,
        widths,
        np.array(tops, np.int32),
        jump_rel=cfg.jump_rel,
        boxes=boxes[tops],
        n_ids=stack.next_id,
        face_sums=stack.sums,
        planes=planes,
    )
    area = stack.attrs[:, 0]
    max_area = cfg.side_max_area * depth.size
    sides = [i for c, i in stack.supports if c == VERTICAL and area[i - 1] < max_area]
    if sides:
        heights = np.zeros(n_facing + 1, np.float64)
        heights[1:] = boxes[1 : n_facing + 1, 3] - boxes[1 : n_facing + 1, 1] + 1
        mean_depth = np.zeros(stack.next_id)
        mean_depth[1:] = stack.attrs[:, 1]
        side = side_faces(
            labels,
            depth,
            heights,
            np.array(sides, np.int32),
            mean_depth,
            jump_rel=cfg.jump_rel,
            boxes=boxes[sides],
            n_ids=stack.next_id,
        )
        for f, sup in side.items():
            top = fronts.setdefault(f, sup)
            if top != sup:
                # a box seen from above: its top folded into a strip of horizontal pixels at its
                # edge and its side runs away beside it: the side joins the same compound
                fronts.setdefault(sup, top)
        if any(f >= stack.first_support for f in fronts):
            fronts = {f: _root(fronts, s) for f, s in fronts.items()}
    if fronts:
        add_rows(stack.sums, boxes, np.array(list(fronts), np.intp), np.array(list(fronts.values()), np.intp))
    return fronts


def _root(fronts: dict[int, int], i: int) -> int:
    """Return the support ``i`` ends in through supports folded into others (a side into a top)."""
    seen = {i}
    while i in fronts and fronts[i] not in seen:
        i = fronts[i]
        seen.add(i)
    return i


def _compound_objects(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    stack: _Stack,
    fronts: dict[int, int],
    below: dict[int, float],
    beneath: dict[int, float],
    bands: Bands,
    intrinsics: Intrinsics | None,
    cam: Intrinsics,
    cfg: SegmentConfig,
    part_scale: tuple[int, int, int] | None = None,
) -> tuple[NDArray[np.int32], list[ObjectSpec], list[list[float]], list[list[int]]]:
    """Return the label map with ids 1..n again and its objects, supports with kinds and parts.

    Facing objects come first; a folded face takes its support's id. The objects are
    described (id, kind, depth label, parts), with their attribute rows and inclusive boxes
    (indexed as :func:`~depthgram.segmentation.attributes.objects_from_rows` reads them), to
    be built once by the caller. ``part_scale``: see :func:`_slices`.
    """
    # a support folded into another (a box's side into its top) is no object of its own
    supports = [(c, i) for c, i in stack.supports if i not in fronts]
    with_front = set(fronts.values())
    n_facing = stack.first_support - 1
    before = stack.attrs
    facing = [i for i in range(1, n_facing + 1) if before[i - 1, 0] > 0 and i not in fronts] + stack.raised
    old = facing + [i for _, i in supports]
    remap = {oid: new for new, oid in enumerate(old, start=1)}
    # without a folded face or a missing id the ids stay 1..n: no pass over the label map
    if fronts or old != list(range(1, stack.next_id)):
        # old id -> new id, a folded face -> its support's new id (a list: a few dozen ids)
        lut = [0] * stack.next_id
        for oid, new in remap.items():
            lut[oid] = new
        for f, sup in fronts.items():
            lut[f] = remap[sup]
        labels = relabel(labels, np.array(lut, np.int32))
    # the floor is the lowest horizontal support with nothing seen beneath it: a table top
    # with the room's floor past its edge is a support of its own kind on every camera
    floor_ids = {i for c, i in supports if c == HORIZONTAL and below[i] > 0 and beneath.get(i, 0.0) < _BENEATH_SHARE}
    lowest = max((i for _, i in supports if i in floor_ids and i not in with_front), key=below.__getitem__, default=0)
    # a folded face's statistics were added to its support's row: those rows' attributes again
    after = attribute_rows(stack.sums, cam) if fronts else before
    rows = after.tolist()
    boxes = stack.boxes.tolist()
    keys = stack.keys.tolist()
    specs = [ObjectSpec(remap[i], "object", keys[i], ()) for i in facing]
    kinds = []
    compounds = []
    for cls, i in supports:
        kind = support_kind(cls, below[i], i == lowest)
        if i in with_front:
            kind = "compound"  # a top with a face below it, or a face with its side: a table, a box
        kinds.append(kind)
        box = boxes[i]
        compounds.append((remap[i], (box[0], box[1], box[2] + 1, box[3] + 1), cls == HORIZONTAL))
    # every support's slice parts in one call, numbered after the objects
    all_parts = compound_parts(
        labels, depth, compounds, step_of=cfg.slice_step, depth_label=bands.depth_label, intrinsics=intrinsics,
        first_id=len(old) + 1, scale=part_scale,
    )  # fmt: skip
    for (_, i), kind, (oid, _, _), parts in zip(supports, kinds, compounds, all_parts, strict=True):
        # the label of the support's mean depth before any face folded into it
        label = min(p.depth_label for p in parts) if parts else int(bands.depth_label(before[i - 1, 1]))
        specs.append(ObjectSpec(oid, kind, label, parts))
    # rows and boxes by the new ids
    return labels, specs, [rows[i - 1] for i in old], [boxes[0], *(boxes[i] for i in old)]


#: A horizontal support with more than this share of the frame's readings lying beneath its
#: plane (by more than :data:`_BENEATH_MM`) is raised (a table top), not the floor.
_BENEATH_SHARE = 0.01
_BENEATH_MM = 150.0


def _below_camera(
    labels: NDArray[np.int32], depth: NDArray[np.float32], cam: Intrinsics, stack: _Stack
) -> tuple[dict[int, float], dict[int, float], dict[int, tuple[float, float, float]]]:
    """Return each support's height below the camera and, for horizontal ones, the readings beneath it and its plane.

    The height is in mm (negative above the camera: a ceiling); the readings beneath are the
    share of the frame's readings seen beneath the support's plane; the plane is ``(a, b, c)``
    of ``1/Z = a x + b y + c`` in pixels (1/mm), the one
    :func:`~depthgram.segmentation.contacts.support_planes` fits, for the front faces' test.

    The centroid's Y says it for a level camera only: a camera pitched down at a table sees the
    table's centroid above its optical axis. The support's fitted plane says it for any pitch:
    its normal turned toward the sensor points up (image -y) for a support seen from above, and
    the plane's offset is the camera's height over it. Walls keep their centroid's Y.
    """
    gy = stack.attrs[:, 6]
    out = {i: float(gy[i - 1]) for _, i in stack.supports}
    # the planes of the horizontal supports only: the others' sums and solves were thrown away
    # (each row's sums and solve are those of a plane fit on the whole map)
    horizontal = [i for c, i in stack.supports if c == HORIZONTAL]
    if not horizontal:
        return out, {}, {}
    ids = np.array(horizontal, np.intp)
    # each support's own box (inclusive) holds all its pixels: the frame outside is not read
    n = stack.next_id - 1
    sums = plane_sums_in_boxes(labels, n, ids, stack.boxes[ids], depth, cam.fx, cam.fy, cam.cx, cam.cy)
    normal, off, _ = planes_from_sums(sums[np.concatenate(([0], ids))])
    # Python floats: a few planes, for which numpy's scalars cost more than the arithmetic
    normals, offsets = normal[1:].tolist(), off[1:].tolist()
    for i, (_, ny, _), d in zip(horizontal, normals, offsets, strict=True):
        out[i] = d if ny < 0 else -d
    # every 4th pixel in 3-D: enough to tell whether anything lies beneath a plane
    shares = shares_beneath(depth, 4, cam, normal[1:], off[1:], _BENEATH_MM)
    # the same planes in pixels for the front faces' test, without a second fit
    planes = planes_in_pixels(normals, offsets, cam.fx, cam.fy, cam.cx, cam.cy)
    return out, dict(zip(horizontal, shares.tolist(), strict=True)), dict(zip(horizontal, planes, strict=True))


def _add_support_planes(
    depth: NDArray[np.float32], ok: NDArray[np.bool_], classes: NDArray[np.int8], cam: Intrinsics, cfg: SegmentConfig
) -> None:
    """Pixels of the dominant oblique planes join the horizontal or wall class (in place).

    The orientation field judges a surface against the camera's axes, so a table top seen at
    45 degrees from above is facing; its plane is found by a robust fit whatever its pitch. The
    plane's normal, not the image axes, says whether it is a horizontal support or a wall.
    """
    planes = find_planes(
        depth,
        ok,
        min_area=cfg.plane_min_area,
        min_spread=cfg.plane_min_spread,
        tol_mm=cfg.plane_tol_mm,
        tol_rel=cfg.plane_tol_rel,
        max_planes=cfg.max_planes,
        # the orientation field's supports need no second search: planes are looked for among
        # the pixels it left facing (a table top seen at a slant), which also keeps it cheap
        search=classes == FACING,
    )
    # a support runs away from the camera: its normal leans at least oblique_deg degrees off the
    # optical axis toward the image's vertical (floor, table) or horizontal (wall) axis. A
    # wall facing a camera that looks slightly down has a normal mostly along the axis, with
    # more y than x in what remains: without this test it became a 2 m "floor" (Azure Kinect)
    lean = math.sin(math.radians(cfg.oblique_deg))
    for plane in planes:
        n = plane_normal(plane.coef, cam)
        if max(abs(n[0]), abs(n[1])) < lean:
            continue
        classes[plane.inliers] = HORIZONTAL if abs(n[1]) >= abs(n[0]) else VERTICAL


def _orientation(
    depth: NDArray[np.float32], ok: NDArray[np.bool_], cam: Intrinsics, cfg: SegmentConfig
) -> tuple[NDArray[np.int8], NDArray[np.float32] | None]:
    """Orientation classes, estimated on every ``k``-th pixel for frames wider than 320 px.

    Orientation is a property of surfaces many pixels wide, so a 2x (4x) subsampled frame gives
    the same classes at a quarter (sixteenth) of the cost; the class map is then repeated back.
    Support pixels are refined at full resolution afterwards (plane test, depth continuity).
    Also returns the frame's 1000 / Z and readings (``creases.inverse_depth``) when the field read
    every pixel, for the creases (None otherwise).
    """
    w = depth.shape[1]
    k = 1 if w <= 320 else 2 if w <= 960 else 4
    if k == 1:
        inverse = inverse_depth(np.ascontiguousarray(depth, np.float32), np.ascontiguousarray(ok, np.bool_))
        cls = orientation_classes(
            depth, ok, cam, window_px=cfg.normal_window_px, oblique_deg=cfg.oblique_deg, jump_rel=cfg.jump_rel,
            inverse=inverse,
        )  # fmt: skip
        return cls, inverse
    sub_cam = Intrinsics(cam.fx / k, cam.fy / k, cam.cx / k, cam.cy / k)
    d, v = np.ascontiguousarray(depth[::k, ::k]), np.ascontiguousarray(ok[::k, ::k])
    cls = orientation_classes(
        d, v, sub_cam, window_px=cfg.normal_window_px, oblique_deg=cfg.oblique_deg, jump_rel=cfg.jump_rel
    )
    return upsample_classes(cls, ok, k), None
