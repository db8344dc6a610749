"""Settings of the wrong kind are refused by name (issue 18.9)."""

from __future__ import annotations

from pathlib import Path

import pytest

from depthgram.errors import InputError
from depthgram.pipeline import Config


@pytest.mark.parametrize(
    ("toml", "name"),
    [
        ('[tree]\nrelations = "false"\n', "relations"),  # was true: a non-empty string
        ("[segment]\nbin_mm = true\n", "bin_mm"),  # was 1 mm
        ('[segment]\nbin_mm = "10"\n', "bin_mm"),  # was a raw TypeError
        ("[segment]\nfill_holes_px = 2.5\n", "fill_holes_px"),
        ("[segment]\nmethod = 3\n", "method"),
        ('[tracker]\nmax_missed = "3"\n', "max_missed"),
    ],
)
def test_a_setting_of_the_wrong_kind_is_refused_by_name(tmp_path: Path, toml: str, name: str) -> None:
    path = tmp_path / "c.toml"
    path.write_text(toml)
    with pytest.raises(InputError, match=rf"{name} = .*expected"):
        Config.load(path)


def test_numbers_of_either_kind_still_load(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text("[segment]\nbin_mm = 8\n[tree]\nrelations = false\n")
    cfg = Config.load(path)
    assert cfg.segment.bin_mm == 8 and cfg.tree.relations is False
    assert Config.from_dict(Config().to_dict()) == Config()


@pytest.mark.parametrize("gain", [1.5, 1e30])
def test_master_gain_is_capped_at_full_scale(gain: float) -> None:
    # a gain of 1e30 made a full-scale square wave: a hearing risk
    with pytest.raises(InputError, match="master_gain"):
        Config.from_dict({"sound": {"master_gain": gain}})
    assert Config.from_dict({"sound": {"master_gain": 1.0}}).sound.master_gain == 1.0
