"""Real accuracy with peers side by side (issue 12, item 4).

On ``../shared/data/ycbv_0000_labelled`` (Asus Xtion, 10 frames, 3 labelled objects each = 30
objects, exact masks rendered from annotated poses), per object: area recall (intersection / true
area), precision (intersection / detected area), IoU and found (IoU >= 0.5) of the best-IoU
segment, from :func:`depthgram.segmentation.evaluate` over the pixels with a reading. Methods, in
the same run on the same frames:

- depthgram's default ``segment`` and ``method="threshold"`` (the paper's), both untuned;
- Open3D: the dominant plane(s) removed with ``segment_plane`` (RANSAC), the rest voxel-down-sampled
  and clustered with ``cluster_dbscan``, each pixel taking the cluster of its nearest kept point
  (within eps). Without Open3D (its wheel needs libusb-1.0 on Linux) a numpy RANSAC plane fit and
  scikit-learn's DBSCAN do the same and the row says so;
- scikit-image ``felzenszwalb`` on the depth image (mm), invalid pixels left out of the scores.

The peers are tuned by a small grid search on the odd frames (1, 3, 5, 7, 9), best mean IoU
(ties: found count); the table scores all 10 frames and, separately, the even (held-out) frames.
The frames are consecutive video frames of a still scene, so held-out frames are close to the
tuning frames: the held-out figure is an honest upper bound on how well the tuning transfers, not
a test on another scene. depthgram is not tuned.

Pictures (depth, truth, each method) go to ``--out`` (default ``benchmarks/out/real/``), one PNG
per frame. ``--others`` prints what the default finds on the other real recordings (7-Scenes,
NVlabs, OSD, Azure Kinect) for eyeballing beside their pictures.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/real.py`` (``--quick``: a smaller grid).
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation import evaluate, segment

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # bench --data
YCBV = SHARED / "ycbv_0000_labelled"
OUT = ROOT / "benchmarks" / "out" / "real"
#: YCB classes present in video 0000 (gelatin box, mug, foam brick); class id = instance id.
OBJECT_IDS = (8, 14, 21)
IOU_FOUND = 0.5

Labeller = Callable[["LabelledFrame", dict[str, Any]], NDArray[np.int32]]


@dataclass(frozen=True)
class LabelledFrame:
    """One YCB-Video frame: depth (mm, 0 = none), truth instance ids, intrinsics (px)."""

    name: str
    depth: NDArray[np.float32]
    valid: NDArray[np.bool_]
    truth: NDArray[np.int32]
    intrinsics: Intrinsics


def load_ycbv(folder: Path = YCBV, frames: Sequence[int] | None = None) -> list[LabelledFrame]:
    """The labelled YCB-Video frames (depth uint16 in 0.1 mm, ``factor_depth`` from meta.mat).

    Parameters
    ----------
    folder : Path
        The recording folder with ``NNNNNN-depth.png``, ``-label.png`` and ``-meta.mat``.
    frames : sequence of int, optional
        Frame numbers (1-based as in the file names); all present by default.
    """
    import scipy.io

    from depthgram.errors import InputError

    numbers = frames or sorted(int(p.name[:6]) for p in folder.glob("*-depth.png"))
    out = []
    for k in numbers:
        stem = folder / f"{k:06d}"
        raw = cv2.imread(f"{stem}-depth.png", cv2.IMREAD_UNCHANGED)
        lab = cv2.imread(f"{stem}-label.png", cv2.IMREAD_UNCHANGED)
        if raw is None or lab is None or raw.dtype != np.uint16:
            raise InputError(f"{stem}-depth.png / -label.png: expected a uint16 depth PNG and a label PNG")
        meta = scipy.io.loadmat(f"{stem}-meta.mat")
        K = meta["intrinsic_matrix"]
        mm_per_unit = 1000.0 / float(np.asarray(meta["factor_depth"]).ravel()[0])
        depth = raw.astype(np.float32) * np.float32(mm_per_unit)
        out.append(
            LabelledFrame(
                name=f"{k:06d}",
                depth=depth,
                valid=raw > 0,
                truth=lab.astype(np.int32),
                intrinsics=Intrinsics(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])),
            )
        )
    return out


# -- the methods -----------------------------------------------------------------------------------


def depthgram_labels(f: LabelledFrame, params: dict[str, Any]) -> NDArray[np.int32]:
    """depthgram's ``segment`` with ``params`` as config overrides."""
    return segment(f.depth, valid=f.valid, intrinsics=f.intrinsics, **params).labels


def _points(f: LabelledFrame) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Back-projected valid pixels (m, N x 3) and their flat pixel indices."""
    idx = np.flatnonzero(f.valid)
    v, u = np.divmod(idx, f.depth.shape[1])
    z = f.depth.ravel()[idx].astype(np.float64) / 1000.0
    cam = f.intrinsics
    pts = np.column_stack(((u - cam.cx) * z / cam.fx, (v - cam.cy) * z / cam.fy, z))
    return pts, idx


def _have_open3d() -> bool:
    try:
        import open3d  # noqa: F401
    except (ImportError, OSError):  # OSError: the wheel's libusb-1.0 missing on Linux
        return False
    return True


def _ransac_plane(pts: NDArray[np.float64], dist: float, iters: int, rng: np.random.Generator) -> NDArray[np.bool_]:
    """Inliers of the plane with most points within ``dist`` (m), plain RANSAC (Open3D's fallback)."""
    best = np.zeros(len(pts), bool)
    if len(pts) < 3:
        return best
    for _ in range(iters):
        a, b, c = pts[rng.choice(len(pts), 3, replace=False)]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n)
        if norm < 1e-12:
            continue
        inl = np.abs((pts - a) @ (n / norm)) < dist
        if inl.sum() > best.sum():
            best = inl
    return best


def plane_dbscan_labels(f: LabelledFrame, params: dict[str, Any]) -> NDArray[np.int32]:
    """Open3D plane removal (``segment_plane``, ``planes`` times) then DBSCAN (``cluster_dbscan``).

    DBSCAN runs on a voxel-down-sampled cloud (voxel = eps / 2) as a robotics user would run it:
    on all ~280 k points of a 640 x 480 frame its neighbour lists do not fit in memory at a
    centimetre eps. Every full-resolution point then takes the cluster of its nearest kept point
    within eps.
    """
    from scipy.spatial import cKDTree

    dist_m = params["plane_mm"] / 1000.0
    eps_m = params["eps_mm"] / 1000.0
    min_points = int(params["min_points"])
    pts, idx = _points(f)
    keep = np.ones(len(pts), bool)
    rng = np.random.default_rng(0)
    use_o3d = _have_open3d()
    if use_o3d:
        import open3d as o3d

        o3d.utility.random.seed(0)
    for _ in range(int(params["planes"])):
        rest = np.flatnonzero(keep)
        if len(rest) < 3:
            break
        if use_o3d:
            pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[rest]))
            _, inl = pc.segment_plane(distance_threshold=dist_m, ransac_n=3, num_iterations=1000)
            keep[rest[np.asarray(inl, dtype=np.intp)]] = False
        else:
            keep[rest[_ransac_plane(pts[rest], dist_m, 1000, rng)]] = False
    rest = np.flatnonzero(keep)
    labels = np.zeros(f.depth.size, np.int32)
    if len(rest) == 0:
        return labels.reshape(f.depth.shape)
    voxel = eps_m / 2.0
    if use_o3d:
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[rest])).voxel_down_sample(voxel)
        small = np.asarray(pc.points)
        cl = np.asarray(pc.cluster_dbscan(eps=eps_m, min_points=min_points))
    else:
        from sklearn.cluster import DBSCAN

        _, first = np.unique(np.floor(pts[rest] / voxel).astype(np.int64), axis=0, return_index=True)
        small = pts[rest][first]
        cl = DBSCAN(eps=eps_m, min_samples=min_points).fit_predict(small)
    if len(small) == 0:
        return labels.reshape(f.depth.shape)
    d, near = cKDTree(small).query(pts[rest], distance_upper_bound=eps_m)
    hit = np.isfinite(d)
    lab = np.full(len(rest), -1, np.int64)
    lab[hit] = cl[near[hit]]
    labels[idx[rest]] = (lab + 1).astype(np.int32)  # DBSCAN noise (-1) -> 0
    return labels.reshape(f.depth.shape)


def felzenszwalb_labels(f: LabelledFrame, params: dict[str, Any]) -> NDArray[np.int32]:
    """scikit-image ``felzenszwalb`` on the depth image (mm); pixels without a reading get 0."""
    from skimage.segmentation import felzenszwalb

    seg = felzenszwalb(
        f.depth, scale=params["scale"], sigma=params["sigma"], min_size=int(params["min_size"]), channel_axis=None
    )
    return np.where(f.valid, seg + 1, 0).astype(np.int32)


@dataclass(frozen=True)
class Method:
    """A row of the table: how to label a frame and the parameter grid to tune over."""

    name: str
    run: Labeller
    grid: dict[str, Sequence[Any]] = field(default_factory=dict)

    def settings(self) -> Iterator[dict[str, Any]]:
        """Every combination of the grid (one empty setting when untuned)."""
        keys = list(self.grid)
        for values in itertools.product(*(self.grid[k] for k in keys)):
            yield dict(zip(keys, values, strict=True))


def methods(quick: bool = False) -> list[Method]:
    """The compared methods; ``quick`` shrinks the peers' grids (for tests and a first look)."""
    plane_name = "Open3D plane + DBSCAN" if _have_open3d() else "RANSAC plane + sklearn DBSCAN (no Open3D)"
    if quick:
        pg: dict[str, Sequence[Any]] = {"planes": (1,), "plane_mm": (10.0,), "eps_mm": (10.0,), "min_points": (10,)}
        fg: dict[str, Sequence[Any]] = {"scale": (300.0,), "sigma": (0.8,), "min_size": (1000,)}
    else:
        pg = {"planes": (1, 2), "plane_mm": (5.0, 10.0, 20.0), "eps_mm": (5.0, 10.0, 20.0), "min_points": (5, 20)}
        fg = {"scale": (100.0, 300.0, 1000.0, 3000.0), "sigma": (0.5, 0.8, 1.5), "min_size": (300, 1000, 3000)}
    return [
        Method("depthgram default", depthgram_labels),
        Method("depthgram threshold", lambda f, p: depthgram_labels(f, {"method": "threshold", **p})),
        Method(plane_name, plane_dbscan_labels, pg),
        Method("skimage felzenszwalb", felzenszwalb_labels, fg),
    ]


# -- scoring ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Scores:
    """Per-object scores of one method over some frames (one row per frame and object)."""

    iou: NDArray[np.float64]
    recall: NDArray[np.float64]
    precision: NDArray[np.float64]

    @property
    def found(self) -> int:
        """Objects with IoU >= 0.5."""
        return int(np.count_nonzero(self.iou >= IOU_FOUND))

    @staticmethod
    def join(parts: Sequence[Scores]) -> Scores:
        """The scores of several frames together."""
        return Scores(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("iou", "recall", "precision")))


def score_frame(labels: NDArray[np.integer], f: LabelledFrame) -> Scores:
    """Per-object IoU, recall and precision of ``labels`` on one frame (pixels with a reading)."""
    ev = evaluate(labels, f.truth, valid=f.valid, truth_ids=list(OBJECT_IDS), iou_found=IOU_FOUND)
    o = ev.objects
    return Scores(np.array([s.iou for s in o]), np.array([s.coverage for s in o]), np.array([s.precision for s in o]))


def tune(method: Method, frames: Sequence[LabelledFrame], progress: bool = True) -> dict[str, Any]:
    """The grid setting with the best mean IoU over ``frames`` (ties: more objects found)."""
    settings = list(method.settings())
    if len(settings) <= 1:
        return settings[0] if settings else {}
    from tqdm import tqdm

    best: tuple[float, int] = (-1.0, -1)
    chosen = settings[0]
    for p in tqdm(settings, desc=f"tuning {method.name}", disable=not progress, leave=False):
        s = Scores.join([score_frame(method.run(f, p), f) for f in frames])
        key = (float(s.iou.mean()), s.found)
        if key > best:
            best, chosen = key, p
    return chosen


@dataclass(frozen=True)
class Result:
    """One method's scores with its chosen parameters and time."""

    method: str
    params: dict[str, Any]
    scores: Scores
    held_out: Scores
    ms_per_frame: float


def run_benchmark(
    frames: Sequence[LabelledFrame],
    *,
    quick: bool = False,
    out: Path | None = OUT,
    progress: bool = True,
) -> list[Result]:
    """Tune the peers on the odd frames, score every method on all frames, draw the pictures.

    Parameters
    ----------
    frames : sequence of LabelledFrame
        In order; frames at even positions (file numbers 1, 3, ...) tune, the others are held out.
    quick : bool
        A one-point grid for the peers.
    out : Path or None
        Folder for one PNG per frame; None draws nothing.
    """
    tune_set = list(frames[0::2])
    held = set(range(1, len(frames), 2))
    results = []
    maps: dict[str, list[NDArray[np.int32]]] = {}
    for m in methods(quick):
        params = tune(m, tune_set, progress)
        per_frame = []
        elapsed = 0.0
        maps[m.name] = []
        # One untimed call first: a method's compiled kernels load (or compile) on its first
        # frame, which had put 580 ms/frame on the paper's threshold (5.8 s over 10 frames).
        m.run(frames[0], params)
        for f in frames:
            t0 = time.perf_counter()
            lab = m.run(f, params)
            elapsed += time.perf_counter() - t0
            per_frame.append(score_frame(lab, f))
            maps[m.name].append(lab)
        results.append(
            Result(
                m.name,
                params,
                Scores.join(per_frame),
                Scores.join([s for i, s in enumerate(per_frame) if i in held]) if held else Scores.join([]),
                1000.0 * elapsed / len(frames),
            )
        )
    if out is not None:
        draw(frames, maps, out)
    return results


# -- pictures and tables ---------------------------------------------------------------------------


def _palette(labels: NDArray[np.integer]) -> NDArray[np.uint8]:
    """Label map in colour: 0 black, each label a fixed pseudo-random colour."""
    rng = np.random.default_rng(7)
    n = int(labels.max(initial=0)) + 1
    colours = rng.integers(60, 256, (n, 3), dtype=np.uint8)
    colours[0] = 0
    return colours[labels]


def _depth_rgb(f: LabelledFrame) -> NDArray[np.uint8]:
    lo, hi = np.percentile(f.depth[f.valid], [1, 99]) if f.valid.any() else (0.0, 1.0)
    gray = (255 * (1 - np.clip((f.depth - lo) / max(hi - lo, 1e-6), 0, 1))).astype(np.uint8)
    rgb = cv2.cvtColor(cv2.applyColorMap(gray, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    rgb[~f.valid] = 0
    return np.asarray(rgb, np.uint8)


def _panel(img: NDArray[np.uint8], title: str) -> NDArray[np.uint8]:
    img = np.ascontiguousarray(img)
    cv2.rectangle(img, (0, 0), (img.shape[1], 26), (0, 0, 0), -1)
    cv2.putText(img, title, (6, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def draw(frames: Sequence[LabelledFrame], maps: dict[str, list[NDArray[np.int32]]], out: Path) -> list[Path]:
    """One PNG per frame: depth, truth, then each method's labels (2 rows of 3 panels)."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for i, f in enumerate(frames):
        panels = [_panel(_depth_rgb(f), f"depth {f.name}"), _panel(_palette(f.truth), "truth")]
        for name, labs in maps.items():
            ev = score_frame(labs[i], f)
            panels.append(_panel(_palette(labs[i]), f"{name}: IoU {ev.iou.mean():.2f}"))
        while len(panels) % 3:
            panels.append(np.zeros_like(panels[0]))
        rows = [np.hstack(panels[j : j + 3]) for j in range(0, len(panels), 3)]
        path = out / f"ycbv_{f.name}.png"
        cv2.imwrite(str(path), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))
        written.append(path)
    return written


def table(results: Sequence[Result], n_frames: int) -> str:
    """The results as text: all frames, then the held-out frames, then the chosen parameters."""
    n = 3 * n_frames
    head = f"{'method':44} {'found':>9} {'mean IoU':>8} {'recall':>7} {'precis.':>7} {'ms/frame':>9}"
    lines = [f"YCB-Video 0000, {n_frames} frames, {n} objects (found = IoU >= {IOU_FOUND})", head]
    for r in results:
        s = r.scores
        lines.append(
            f"{r.method:44} {s.found:>4d} of {n:<2d} {s.iou.mean():8.3f} {s.recall.mean():7.3f}"
            f" {s.precision.mean():7.3f} {r.ms_per_frame:9.1f}"
        )
    held = results[0].held_out.iou.size if results else 0
    if held:
        lines += ["", f"held-out frames only (even file numbers, {held} objects; the peers were tuned on the odd ones)"]
        for r in results:
            s = r.held_out
            lines.append(
                f"{r.method:44} {s.found:>4d} of {held:<2d} {s.iou.mean():8.3f} {s.recall.mean():7.3f}"
                f" {s.precision.mean():7.3f}"
            )
    lines += ["", "chosen parameters (grid search on the odd frames, best mean IoU):"]
    lines += [f"  {r.method}: {r.params or 'defaults, untuned'}" for r in results]
    return "\n".join(lines)


#: Other real recordings: (name, depth files glob, invalid raw values, intrinsics (px), at most frames).
OTHERS: tuple[tuple[str, str, tuple[int, ...], Intrinsics, int], ...] = (
    ("7scenes_redkitchen_seq", "depth/frame-*.depth.png", (65535,), Intrinsics(585.0, 585.0, 320.0, 240.0), 10),
    ("nvlabs_ucn_demo_tabletop", "*-depth.png", (), Intrinsics(612.937, 613.173, 322.549, 248.158), 9),
    ("osd_samples_uoais", "disparity/*.png", (), Intrinsics(570.0, 570.0, 320.0, 240.0), 5),
    ("azure_kinect_tof_mug_single", "depth.png", (), Intrinsics(504.6, 504.7, 333.0, 349.0), 1),
)


def others_summary(out: Path | None = OUT) -> str:
    """What the default finds on the other recordings, per recording (counts, kinds), for eyeballing."""
    from depthgram.frame import make_frame
    from depthgram.segmentation import SegmentConfig
    from depthgram.views.pictures import overlay_image

    lines = [f"{'recording':28} {'frames':>6} {'objects/frame':>13}  kinds over all frames (count)"]
    for name, pattern, invalid, cam, most in OTHERS:
        paths = sorted((SHARED / name).glob(pattern))
        if not paths:
            continue
        step = max(1, len(paths) // most)
        picks = paths[::step][:most]
        counts: list[int] = []
        kinds: Counter[str] = Counter()
        for p in picks:
            raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            if raw is None:
                continue
            fr = make_frame(raw, invalid_values=list(invalid), intrinsics=cam, name=str(p))
            seg = segment(fr.depth, valid=fr.valid, intrinsics=cam, config=SegmentConfig())
            counts.append(len(seg.objects))
            kinds.update(o.kind for o in seg.objects)
            if out is not None:
                out.mkdir(parents=True, exist_ok=True)
                stem = p.name.replace(".png", "").replace(".depth", "")
                img = overlay_image(fr, seg, scale=1)
                cv2.imwrite(str(out / f"{name}_{stem}.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        kinds_text = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items(), key=lambda kv: -kv[1]))
        lines.append(f"{name:28} {len(picks):6d} {np.mean(counts):13.1f}  {kinds_text}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--quick", action="store_true", help="one grid point per peer (a first look in a minute)")
    p.add_argument("--frames", type=int, default=0, help="use only the first N frames (0 = all 10)")
    p.add_argument("--out", type=Path, default=OUT, help=f"folder for the pictures (default {OUT})")
    p.add_argument("--no-others", action="store_true", help="skip the summaries of the other recordings")
    args = p.parse_args(argv)
    if not YCBV.is_dir():
        print(f"labelled recording not found at {YCBV}: nothing to score", file=sys.stderr)
        return 0
    frames = load_ycbv()
    if args.frames:
        frames = frames[: args.frames]
    results = run_benchmark(frames, quick=args.quick, out=args.out)
    print(table(results, len(frames)))
    if not args.no_others:
        print("\nthe default on the other real recordings (look at the pictures in the output folder):")
        print(others_summary(args.out))
    print(f"\npictures: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
