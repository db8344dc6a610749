"""The paper's Table 1 for this implementation: thresholding, thresholding with slicing, region growing.

On the simulator's scenes (seeded, ground truth): which kinds of objects each method finds,
area % (share of the true area labelled by segments assigned to the right object) and
precision, share of objects found at IoU >= 0.5, Hoover et al. counts at T = 0.8, and time as a
multiple of thresholding. On the real recordings in ../shared/data (no masks): objects found,
share of valid pixels labelled, time.

Run: ``.venv/bin/python benchmarks/table1.py`` (``--readings`` adds the paper's two readings of
the 10 % rule and the gap-pixel choice; ``--paper`` the paper's own slicing at several apertures
and directions; ``--size 640x480`` for another resolution; ``--tabletop`` only the real tabletop
frames: objects standing on the support against a count by eye, and the support found).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from depthgram.segmentation import SegmentConfig, evaluate, segment

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # bench --data

#: (row name, segment overrides). Region growing uses the tolerance that scored best on the
#: ``table`` scene in a sweep over 5, 10, 20, 40 mm per metre (see ``--sweep``).
METHODS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("thresholding", {"method": "threshold"}),
    ("thresholding + slicing", {"method": "slices"}),
    ("surfaces (default)", {"method": "surfaces"}),
    ("surfaces, every pixel", {"method": "surfaces", "work_width_px": 0}),
    ("region growing", {"method": "region", "region_tol_mm": 10.0}),
    ("paper slicing (3%, both)", {"method": "paper"}),
)
#: The paper's own slicing (``method="paper"``) at several apertures (fraction of the frame
#: height / width) and directions: "several directions and slice aperture sizes must be tried".
PAPER_READINGS: tuple[tuple[str, dict[str, Any]], ...] = tuple(
    (f"paper slicing ({100 * ap:g}%, {d})", {"method": "paper", "paper_aperture_fraction": ap, "slice_directions": d})
    for ap in (0.05, 0.10, 0.20)
    for d in ("horizontal", "vertical", "both")
)
READINGS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("slices, cut 10% before minimum, gaps background", {"gap_pixels": "background"}),
    ("slices, cut 10% past peak, gaps background", {"cut_from": "peak", "gap_pixels": "background"}),
    ("threshold, cut 10% before minimum, gaps background", {"method": "threshold", "gap_pixels": "background"}),
    (
        "threshold, cut 10% past peak, gaps background",
        {"method": "threshold", "cut_from": "peak", "gap_pixels": "background"},
    ),
    ("slices, depth-dependent bins", {"depth_dependent_bins": True}),
    ("slices, horizontal slices only", {"slice_directions": "horizontal"}),
    ("slices, vertical slices only", {"slice_directions": "vertical"}),
    ("slices, aperture 5% of the object", {"slice_aperture_fraction": 0.05}),
    ("slices, aperture 20% of the object", {"slice_aperture_fraction": 0.20}),
)
#: Scene name -> frame index used (crossing: both movers in view at t = 1 s).
SCENES = {"table": 0, "corridor": 0, "crossing": 30}


@dataclass(frozen=True)
class Row:
    """One method on one scene (or recording)."""

    source: str
    method: str
    objects: int
    kinds_found: str
    area: float
    precision: float
    found: float
    correct: int
    over: int
    under: int
    missed: int
    time_ms: float
    time_ratio: float
    labelled: float


def _time(fn: Any, repeat: int) -> tuple[Any, float]:
    out = fn()  # warm-up (numba compile, caches)
    t0 = time.perf_counter()
    for _ in range(repeat):
        out = fn()
    return out, (time.perf_counter() - t0) / repeat * 1e3


def run_table1(
    *,
    size: tuple[int, int] = (176, 132),
    seed: int = 0,
    repeat: int = 5,
    methods: Sequence[tuple[str, dict[str, Any]]] = METHODS,
    real: bool = True,
) -> list[Row]:
    """Rows of Table 1: every method on every simulator scene, then on the real recordings."""
    from depthgram.sensor import simulate

    rows: list[Row] = []
    for scene, index in SCENES.items():
        sim = list(simulate(scene, index + 1, size=size, seed=seed))[index]
        f = sim.frame
        ids = [t.id for t in sim.truth if t.area > 0]
        kind_of = {t.id: t.kind for t in sim.truth}
        base = None
        for name, kw in methods:
            cfg = SegmentConfig(**kw)

            run = partial(segment, f.depth, valid=f.valid, intrinsics=f.intrinsics, config=cfg)
            seg, ms = _time(run, repeat)
            base = base or ms
            ev = evaluate(seg.labels, sim.instances, valid=f.valid, truth_ids=ids)
            kinds = sorted({kind_of[s.truth_id] for s in ev.objects if s.iou >= 0.5})
            rows.append(
                Row(
                    source=f"sim:{scene}#{index}",
                    method=name,
                    objects=len(seg.objects),
                    kinds_found="+".join(kinds) or "-",
                    area=ev.area_assigned,
                    precision=ev.precision_assigned,
                    found=ev.found_share,
                    correct=ev.correct,
                    over=ev.over,
                    under=ev.under,
                    missed=ev.missed,
                    time_ms=ms,
                    time_ratio=ms / base,
                    labelled=float(np.count_nonzero(seg.labels)) / max(int(f.valid.sum()), 1),
                )
            )
    if real and SHARED.is_dir():
        rows.extend(_real_rows(methods, repeat))
    return rows


def _real_rows(methods: Sequence[tuple[str, dict[str, Any]]], repeat: int) -> list[Row]:
    from depthgram.frame import Intrinsics, make_frame

    try:
        import cv2
    except ImportError:  # pragma: no cover
        return []
    picks = [
        ("azure_kinect_tof_mug_single/depth.png", Intrinsics(504.6, 504.7, 333.0, 349.0)),
        ("nvlabs_ucn_demo_tabletop/000000-depth.png", Intrinsics(612.937, 613.173, 322.549, 248.158)),
        ("7scenes_redkitchen_seq/depth/frame-000000.depth.png", Intrinsics(585.0, 585.0, 320.0, 240.0)),
    ]
    rows: list[Row] = []
    for rel, cam in picks:
        path = SHARED / rel
        if not path.is_file():
            continue
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        f = make_frame(raw, invalid_values=[65535], intrinsics=cam, name=rel)
        base = None
        for name, kw in methods:
            cfg = SegmentConfig(**kw)

            run = partial(segment, f.depth, valid=f.valid, intrinsics=f.intrinsics, config=cfg)
            seg, ms = _time(run, max(1, repeat // 2))
            base = base or ms
            kinds = sorted({o.kind for o in seg.objects})
            rows.append(
                Row(
                    rel.split("/")[0],
                    name,
                    len(seg.objects),
                    "+".join(kinds) or "-",
                    float("nan"),
                    float("nan"),
                    float("nan"),
                    0,
                    0,
                    0,
                    0,
                    ms,
                    ms / base,
                    float(np.count_nonzero(seg.labels)) / max(int(f.valid.sum()), 1),
                )
            )
    return rows


#: Objects of at least ~1 % of the frame standing on the table, counted by eye in the colour
#: images beside the depth frames (NVlabs: RealSense, intrinsics in camera_params.json; OSD:
#: Kinect v1, nominal intrinsics).
TABLETOP_BY_EYE: dict[str, int] = {
    **{f"nvlabs_ucn_demo_tabletop/{i:06d}-depth.png": n for i, n in enumerate((10, 10, 9, 10, 4, 3, 10, 3, 7))},
    **{
        f"osd_samples_uoais/disparity/{k}.png": n
        for k, n in (("learn6", 2), ("test42", 3), ("test50", 7), ("test63", 13), ("test64", 13))
    },
}


def tabletop_rows(**overrides: Any) -> list[str]:
    """One line per real tabletop frame: objects on the largest support, count by eye, support.

    "on support" counts segments of kind ``object`` or ``compound`` (>= 0.3 % of the frame, nearer than 1.2 m)
    whose centre lies in the support's box; a split object counts once per piece, so compare
    it with the count by eye together with the overlay pictures (``depthgram report``).
    """
    import cv2

    from depthgram.frame import Intrinsics

    cams = {
        "nvlabs_ucn_demo_tabletop": Intrinsics(612.937, 613.173, 322.549, 248.158),
        "osd_samples_uoais": Intrinsics(570.0, 570.0, 320.0, 240.0),
    }
    lines = [f"{'frame':44} {'on support':>10} {'by eye':>6}  support (kind, % of frame, mean depth mm)"]
    for rel, by_eye in TABLETOP_BY_EYE.items():
        path = SHARED / rel
        if not path.is_file():
            continue
        z = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float32)
        seg = segment(z, valid=z > 0, intrinsics=cams[rel.split("/")[0]], **overrides)
        supports = [o for o in seg.objects if o.kind != "object"]
        if not supports:
            lines.append(f"{rel:44} {'-':>10} {by_eye:6d}  none")
            continue
        sup = max(supports, key=lambda o: o.area)
        x0, y0, x1, y1 = sup.bbox_xy  # half-open
        on = sum(
            1
            for o in seg.objects
            if o.kind in ("object", "compound")  # a box's top with its front face is a compound
            and o.id != sup.id
            and o.area_fraction >= 0.003
            and o.depth < 1200.0
            and x0 <= o.center_xy[0] <= x1 - 1
            and y0 <= o.center_xy[1] <= y1 - 1
        )
        lines.append(f"{rel:44} {on:10d} {by_eye:6d}  {sup.kind}, {100 * sup.area_fraction:.1f} %, {sup.depth:.0f}")
    return lines


def format_rows(rows: Sequence[Row]) -> str:
    """Rows as a fixed-width text table."""
    head = (
        f"{'source':28} {'method':48} {'obj':>4} {'area%':>6} {'prec%':>6} {'found':>6} "
        f"{'C/O/U/M':>9} {'lab%':>5} {'ms':>8} {'x':>5}  kinds found (IoU>=0.5)"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        hv = f"{r.correct}/{r.over}/{r.under}/{r.missed}" if r.area == r.area else "-"
        area = f"{100 * r.area:6.1f}" if r.area == r.area else f"{'-':>6}"
        prec = f"{100 * r.precision:6.1f}" if r.precision == r.precision else f"{'-':>6}"
        found = f"{r.found:6.2f}" if r.found == r.found else f"{'-':>6}"
        lines.append(
            f"{r.source:28} {r.method:48} {r.objects:4d} {area} {prec} {found} {hv:>9} "
            f"{100 * r.labelled:5.1f} {r.time_ms:8.2f} {r.time_ratio:5.1f}  {r.kinds_found}"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print Table 1; return the exit status."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="176x132", help="simulated frame size WxH (default 176x132)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeat", type=int, default=5, help="timed runs per method")
    p.add_argument("--readings", action="store_true", help="also the two readings of the 10%% rule")
    p.add_argument("--sweep", action="store_true", help="also region growing at several tolerances")
    p.add_argument("--paper", action="store_true", help="also the paper's slicing, 3 apertures x 3 directions")
    p.add_argument("--no-real", action="store_true", help="skip the real recordings")
    p.add_argument("--quick", action="store_true", help="one timed run, simulator scenes only")
    p.add_argument("--tabletop", action="store_true", help="only the real tabletop frames (objects on the support)")
    args = p.parse_args(argv)
    if args.tabletop:
        if not SHARED.is_dir():
            print(f"real recordings not found at {SHARED}")
            return 1
        print("\n".join(tabletop_rows()))
        print("\nwithout support planes (orientation field only):")
        print("\n".join(tabletop_rows(support_planes=False)))
        return 0
    if args.quick:
        args.repeat, args.no_real = 1, True
    w, h = (int(v) for v in args.size.lower().split("x"))
    methods = list(METHODS)
    if args.readings:
        methods += [(n, {"method": "slices", **kw}) for n, kw in READINGS]
    if args.paper:
        methods += list(PAPER_READINGS)
    if args.sweep:
        methods += [(f"region growing {t:g} mm/m", {"method": "region", "region_tol_mm": t}) for t in (5, 20, 40)]
    rows = run_table1(size=(w, h), seed=args.seed, repeat=args.repeat, methods=methods, real=not args.no_real)
    print(format_rows(rows))
    if not args.no_real and SHARED.is_dir():
        print()
        print("\n".join(tabletop_rows()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
