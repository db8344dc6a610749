"""The per-method groups of SegmentConfig: read from the flat fields, given in TOML as tables."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from depthgram.errors import InputError
from depthgram.pipeline import Config
from depthgram.segmentation import SegmentConfig
from depthgram.segmentation.config import (
    HistogramConfig,
    PaperConfig,
    PlaneConfig,
    RegionConfig,
    SliceConfig,
    SurfaceConfig,
)

GROUPS = {
    "histogram": HistogramConfig,
    "slices": SliceConfig,
    "planes": PlaneConfig,
    "surfaces": SurfaceConfig,
    "region": RegionConfig,
    "paper": PaperConfig,
}


def test_every_group_reads_its_flat_fields_and_no_field_is_in_two_groups() -> None:
    cfg = SegmentConfig(paper_min_slices=5, plane_tol_mm=6.0, crease_deg=35.0, region_relative=False)
    seen: set[str] = set()
    for name, group in GROUPS.items():
        got = getattr(cfg, name)
        assert isinstance(got, group)
        for short, flat in group.FLAT.items():  # type: ignore[attr-defined]
            assert getattr(got, short) == getattr(cfg, flat)
            assert flat not in seen
            seen.add(flat)
        assert [f.name for f in dataclasses.fields(group)] == list(group.FLAT)  # type: ignore[attr-defined]
    assert cfg.paper.min_slices == 5 and cfg.planes.tol_mm == 6.0 and not cfg.region.relative
    # what no group holds: the method, the shared object size and hole limits, the far limit
    # and the deprecated spellings
    rest = {f.name for f in dataclasses.fields(SegmentConfig)} - seen
    assert rest == {
        "method", "min_area_fraction", "min_area_px", "min_area", "fill_holes_px", "slice_aperture",
        "paper_aperture", "far_mm",
    }  # fmt: skip


def test_groups_as_toml_tables_and_flat_keys_give_one_config(tmp_path: Path) -> None:
    nested = tmp_path / "nested.toml"
    nested.write_text(
        "[segment]\nbin_mm = 7.0\n[segment.paper]\nmin_slices = 5\n[segment.planes]\nenabled = false\n",
        encoding="utf-8",
    )
    flat = tmp_path / "flat.toml"
    flat.write_text("[segment]\nbin_mm = 7.0\npaper_min_slices = 5\nsupport_planes = false\n", encoding="utf-8")
    assert (
        Config.load(nested).segment
        == Config.load(flat).segment
        == SegmentConfig(bin_mm=7.0, paper_min_slices=5, support_planes=False)
    )
    # the config is written back with the flat keys, which load again
    back = tmp_path / "back.toml"
    Config.load(nested).save(back)
    assert Config.load(back) == Config.load(flat)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"paper": {"no_such": 1}}, "unknown paper setting"),
        ({"paper": {"min_slices": 4}, "paper_min_slices": 4}, "given twice"),
        ({"paper": {"min_slices": 4.5}}, "expected an integer"),
        ({"planes": {"enabled": 1}}, "expected true or false"),
        ({"planes": 3}, "must be a table"),
        ({"no_such_setting": 1}, "unknown setting"),
    ],
)
def test_wrong_groups_are_refused(values: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        SegmentConfig.from_dict(values)
