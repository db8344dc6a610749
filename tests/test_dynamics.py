"""Range-flow building blocks: the velocity fit (eq. 13), time to collision, matching, config."""

from __future__ import annotations

import math

import numpy as np
import pytest

from depthgram.dynamics import (
    TrackerConfig,
    assign,
    bbox_iou,
    fit_radial_velocity,
    match_cost,
    time_to_collision,
)
from depthgram.dynamics.match import FORBIDDEN
from depthgram.errors import InputError


def test_two_entries_is_equation_13() -> None:
    # 10 mm closer in 0.1 s: -100 mm/s.
    v, z = fit_radial_velocity([0.0, 0.1], [1000.0, 990.0])
    assert v == pytest.approx(-100.0)
    assert z == pytest.approx(990.0)


def test_least_squares_slope_hand_computed() -> None:
    # t = 0..3, z = 0, 1, 1, 3: tbar 1.5, zbar 1.25, sum dt*dz = 4.5, sum dt^2 = 5 -> 0.9.
    v, z = fit_radial_velocity([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 1.0, 3.0])
    assert v == pytest.approx(0.9)
    assert z == pytest.approx(1.25 + 0.9 * 1.5)


def test_invalid_entries_are_skipped_not_zero() -> None:
    v, z = fit_radial_velocity([0.0, 1.0, 2.0], [1000.0, np.nan, 980.0])
    assert v == pytest.approx(-10.0)
    assert z == pytest.approx(980.0)
    v, z = fit_radial_velocity([0.0, 1.0, 2.0], [np.nan, 1200.0, np.nan])
    assert math.isnan(v) and z == pytest.approx(1200.0)
    v, z = fit_radial_velocity([0.0, 1.0], [np.nan, np.nan])
    assert math.isnan(v) and math.isnan(z)


def test_many_rows_and_large_timestamps() -> None:
    t0 = 1.7e9  # Unix seconds: the fit centres on t_now to keep precision
    t = t0 + np.array([[0.0, 1 / 30, 2 / 30, 3 / 30], [0.0, 1 / 30, 2 / 30, 3 / 30]])
    z = np.array([[2000.0, 1990.0, 1980.0, 1970.0], [500.0, 510.0, np.nan, 530.0]])
    v, zn = fit_radial_velocity(t, z)
    np.testing.assert_allclose(v, [-300.0, 300.0], rtol=1e-6)
    np.testing.assert_allclose(zn, [1970.0, 530.0], rtol=1e-9)


def test_time_to_collision() -> None:
    ttc = time_to_collision([1000.0, 1000.0, 1000.0, 1000.0], [-250.0, 250.0, -10.0, np.nan], 50.0)
    assert ttc[0] == pytest.approx(4.0)
    assert np.isnan(ttc[1:]).all()


def test_bbox_iou_hand_computed() -> None:
    a = np.array([[0.0, 0.0, 10.0, 10.0]])  # half-open: 10 x 10 px
    b = np.array([[5.0, 0.0, 15.0, 10.0], [0.0, 0.0, 10.0, 10.0], [20.0, 20.0, 31.0, 31.0]])
    np.testing.assert_allclose(bbox_iou(a, b), [[50 / 150, 1.0, 0.0]])


def test_assignment_is_global_not_greedy() -> None:
    # Greedy (row 0 takes its cheapest, col 0) would leave row 1 with cost 10: total 11.
    cost = np.array([[1.0, 2.0], [1.5, 10.0]])
    rows, cols = assign(cost)
    assert dict(zip(rows.tolist(), cols.tolist(), strict=True)) == {0: 1, 1: 0}


def test_assignment_drops_forbidden_pairs() -> None:
    cost = np.array([[FORBIDDEN, 0.5], [FORBIDDEN, FORBIDDEN]])
    rows, cols = assign(cost)
    assert rows.tolist() == [0] and cols.tolist() == [1]
    r, c = assign(np.zeros((0, 3)))
    assert len(r) == len(c) == 0


@pytest.mark.parametrize(
    "kwargs",
    [
        {"queue_length": 1},
        {"queue_length": 2.5},
        {"min_hits": 0},
        {"max_missed": -1},
        {"max_center_rate": 0.0},
        {"fps": 0.0},
        {"center_tau_s": -1.0},
        {"max_area_ratio": 1.0},
        {"max_area_jump": 0.5},
        {"min_iou": 1.5},
        {"min_speed": -1.0},
        {"min_speed": float("nan")},
        {"w_depth": True},
        {"border_px": -2},
    ],
)
def test_config_rejects_absurd_values(kwargs: dict[str, object]) -> None:
    with pytest.raises(InputError, match="TrackerConfig"):
        TrackerConfig(**kwargs)  # type: ignore[arg-type]


def test_config_defaults_follow_the_paper() -> None:
    c = TrackerConfig()
    assert c.queue_length >= 3  # "three or more will increase the robustness"
    assert TrackerConfig(queue_length=2, max_depth_rate=1).queue_length == 2  # TOML ints accepted


def test_match_cost_hand_computed_and_gates() -> None:
    cfg = TrackerConfig()  # center gate 3/s * diagonal, depth gate 6/s, weights 1, 1, 0.5, 1, 0.2

    def cost(obj_depth: float, elapsed: float, dt: float = 1 / 30) -> float:
        c = match_cost(
            [[100.0, 100.0]], [1000.0], [400.0], [[90.0, 90.0, 110.0, 110.0]], [0], [elapsed],
            [[110.0, 100.0]], [obj_depth], [400.0], [[100.0, 90.0, 120.0, 110.0]], [1],
            800.0, dt, cfg,
        )  # fmt: skip
        return float(c[0, 0])

    # at 30 frames/s: center 10/80, depth 50/200, area 0, 1 - IoU = 1 - 200/600, label mismatch 0.2
    assert cost(1050.0, 1 / 30) == pytest.approx(10 / 80 + 50 / 200 + 2 / 3 + 0.2)
    assert cost(1300.0, 1 / 30) == FORBIDDEN  # 30 % depth change in one frame
    # After one missed frame the depth gate doubles and the center gate grows by 25 %.
    assert cost(1300.0, 2 / 30) == pytest.approx(10 / 100 + 300 / 400 + 2 / 3 + 0.2)
    # At 10 frames/s the same 30 % in one frame step is within the gate (60 % per 0.1 s).
    assert cost(1300.0, 0.1, 0.1) == pytest.approx(10 / 240 + 300 / 600 + 2 / 3 + 0.2)
