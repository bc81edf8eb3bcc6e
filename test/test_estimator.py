# Copyright 2026 The lookahead_control Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.


"""The rear-compliance estimator against the single-track model's own signals."""

import math

from lookahead_control.core.control_law import LateralState
from lookahead_control.core.estimator import (brush_shape, ComplianceEstimator, GRAVITY,
                                              MAX_LOAD)
from lookahead_control.core.params import VehicleParams
import numpy as np
import pytest

VEHICLE = VehicleParams()


def estimator(time_constant=0.5, filter_time=0.3, prior=0.5, ratio=3.0, friction=0.0):
    return ComplianceEstimator(VEHICLE, time_constant, filter_time, prior, ratio, friction)


def cornering(c_r, v_x, a_y):
    """Steady cornering of a plant with rear stiffness c_r: (v_y, r) by hand."""
    r = a_y / v_x
    alpha_r = VEHICLE.mass * VEHICLE.l1 / (c_r * VEHICLE.wheelbase) * a_y
    return VEHICLE.l2 * r - v_x * alpha_r, r


def state(v_y, r, v_x):
    return LateralState(0.0, 0.0, v_y, r, v_x, 0.0, 0.0, 0.0)


def test_prior_before_any_cornering_and_on_a_straight():
    est = estimator()
    assert est.compliance() == VEHICLE.eta
    for _ in range(500):
        est.update(state(0.0, 0.0, 30.0), 0.01, True)
    assert est.compliance() == pytest.approx(VEHICLE.eta, rel=1e-12)


@pytest.mark.parametrize('factor', [0.7, 1.0, 1.3])
def test_steady_cornering_gives_the_secant_compliance(factor):
    # D -> a_y^2, N -> c a_y^2: c_hat = (a^2 c + p^2 eta) / (a^2 + p^2), hand-computed
    v_y, r = cornering(factor * VEHICLE.c_r, 30.0, 3.0)
    est = estimator()
    for _ in range(2000):
        est.update(state(v_y, r, 30.0), 0.01, True)
    truth = VEHICLE.eta / factor
    expected = (9.0 * truth + 0.25 * VEHICLE.eta) / 9.25
    assert est.compliance() == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize('factor', [0.7, 1.0])
def test_transients_of_the_linear_plant_do_not_bias_the_estimate(factor):
    # the single-track plant (sim_plant, linear tyres, C_r scaled) steered by a 0.5 Hz
    # sine: v_x r alone is not the rear force (v_y' and r' matter); the regressor is, so
    # the estimate stays at the plant's compliance throughout the transient
    from sim_plant.vehicle_model import derivatives, PlantParams, rk4_step
    plant_vehicle = VehicleParams(c_r=factor * VEHICLE.c_r)
    plant = PlantParams(model='linear')
    v_x, x, est = 30.0, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0), estimator(filter_time=0.1)
    worst = 0.0
    for k in range(600):
        t = 0.01 * k
        command = 0.01 * math.sin(math.pi * t)
        est.update(state(x[3], x[4], v_x), 0.01 if k else 0.0, True)
        if t > 2.0:     # the prior's share, computed from the filtered D
            truth = VEHICLE.eta / factor
            expected = (truth * est.energy + 0.25 * VEHICLE.eta) / (est.energy + 0.25)
            worst = max(worst, abs(est.compliance() / expected - 1.0))
        for j in range(10):
            x = rk4_step(lambda tt, xx: derivatives(xx, command, v_x, 0.0, 0.0,
                                                    plant_vehicle, plant),
                         t + 0.001 * j, x, 0.001)
    assert worst < 0.02


def test_inactive_samples_teach_nothing_and_the_clip_holds():
    v_y, r = cornering(0.05 * VEHICLE.c_r, 30.0, 3.0)      # 20x softer: beyond the clip
    est = estimator()
    for _ in range(500):
        est.update(state(v_y, r, 30.0), 0.01, False)
    assert est.compliance() == VEHICLE.eta
    for _ in range(2000):
        est.update(state(v_y, r, 30.0), 0.01, True)
    assert est.compliance() == pytest.approx(3.0 * VEHICLE.eta)


def test_batch_forget_and_reset():
    v_y, r = cornering(0.7 * VEHICLE.c_r, 30.0, 3.0)
    est = estimator()
    for _ in range(500):
        est.update(state(np.array([v_y, v_y]), np.array([r, r]), np.array([30.0, 30.0])),
                   0.01, np.array([True, True]))
    est.forget(np.array([True, False]))
    c = est.compliance()
    assert c[0] == VEHICLE.eta and c[1] > 1.2 * VEHICLE.eta
    est.reset()
    assert est.compliance() == VEHICLE.eta and est.filtered is None


# -- load-dependent (brush) compliance ------------------------------------------------------

def test_brush_shape_by_hand():
    # n = 0.35: 0.65^(1/3) = exp(ln 0.65 / 3) = 0.866239; s = 3 (1 - 0.866239) / 0.35
    # = 1.146523; tangent 1 / 0.866239^2 = 1.332676
    secant, tangent = brush_shape(0.35)
    assert secant == pytest.approx(1.146523, abs=2e-6)
    assert tangent == pytest.approx(1.332676, abs=2e-6)
    assert brush_shape(0.0) == (1.0, 1.0)
    assert brush_shape(-0.35)[0] == secant              # symmetric in the load
    assert brush_shape(5.0) == brush_shape(MAX_LOAD)   # clipped short of saturation
    batch = brush_shape(np.array([0.0, 1e-9, 0.35]))
    assert batch[0] == pytest.approx([1.0, 1.0, secant], rel=1e-9)
    assert math.isnan(brush_shape(math.nan)[0])


@pytest.mark.parametrize('load', [0.1, 0.35, 0.6, 0.85])
def test_brush_shape_is_the_fiala_axle_secant(load):
    # independent: solve the plant's Fiala force for the slip at F = n F_max by bisection;
    # the secant compliance over the linear tyre's is C tan(alpha) / F
    from sim_plant.vehicle_model import fiala_force
    stiffness, limit = 80000.0, 6000.0
    low, high = 0.0, 3.0 * limit / stiffness
    for _ in range(200):
        mid = 0.5 * (low + high)
        if -fiala_force(math.atan(mid), stiffness, limit) < load * limit:
            low = mid
        else:
            high = mid
    assert brush_shape(load)[0] == pytest.approx(stiffness * low / (load * limit), rel=1e-9)
    # tangent = d(n s(n)) / dn by a central difference
    h = 1e-6
    slope = ((load + h) * brush_shape(load + h)[0]
             - (load - h) * brush_shape(load - h)[0]) / (2 * h)
    assert brush_shape(load)[1] == pytest.approx(slope, rel=1e-6)


def fiala_cornering(friction, design_friction, v_x, a_y):
    """Steady cornering of a Fiala rear axle at ``friction``: (v_y, r) by hand."""
    r = a_y / v_x
    n = a_y / (friction * GRAVITY)
    tan_alpha = VEHICLE.eta * a_y * 3.0 * (1.0 - (1.0 - n) ** (1.0 / 3.0)) / n
    return VEHICLE.l2 * r - v_x * tan_alpha, r


@pytest.mark.parametrize('a_y', [2.0, 5.0])
def test_shaped_estimate_of_the_design_tyre_stays_at_eta(a_y):
    # a Fiala rear axle at the design friction: the shape is exact, the scale is eta
    v_y, r = fiala_cornering(1.0, 1.0, 30.0, a_y)
    est = estimator(friction=1.0)
    for _ in range(2000):
        est.update(state(v_y, r, 30.0), 0.01, True)
    assert est.compliance() == pytest.approx(VEHICLE.eta, rel=1e-6)
    secant, tangent = est.at(a_y)
    assert secant == pytest.approx(VEHICLE.eta * brush_shape(a_y / GRAVITY)[0], rel=1e-6)
    assert tangent == pytest.approx(VEHICLE.eta * brush_shape(a_y / GRAVITY)[1], rel=1e-6)


def test_shaped_estimate_learns_the_scale_of_a_slippery_road():
    # friction 0.7, design 1.0, a_y = 4: slip = eta a s(4 / 0.7 g); regressor a s(4 / g):
    # c_hat = (a^2 s1^2 eta s07 / s1 + p^2 eta) / (a^2 s1^2 + p^2), hand-computed
    a_y = 4.0
    v_y, r = fiala_cornering(0.7, 1.0, 30.0, a_y)
    est = estimator(friction=1.0)
    for _ in range(3000):
        est.update(state(v_y, r, 30.0), 0.01, True)
    s07 = brush_shape(a_y / (0.7 * GRAVITY))[0]
    s10 = brush_shape(a_y / GRAVITY)[0]
    phi = a_y * s10
    expected = VEHICLE.eta * (phi * a_y * s07 + 0.25) / (phi * phi + 0.25)
    assert est.compliance() == pytest.approx(expected, rel=1e-6)
    # at the learned load the secant compliance is the plant's (up to the prior's share)
    assert est.at(a_y)[0] == pytest.approx(VEHICLE.eta * s07, rel=0.01)


def test_shaped_estimator_batch_equals_single_runs():
    loads = (1.0, 4.0, 6.0)
    pairs = [fiala_cornering(0.8, 1.0, 30.0, a) for a in loads]
    batch, singles = estimator(friction=1.0), [estimator(friction=1.0) for _ in loads]
    v_y = np.array([p[0] for p in pairs])
    r = np.array([p[1] for p in pairs])
    for _ in range(300):
        batch.update(state(v_y, r, np.full(3, 30.0)), 0.01, np.array([True] * 3))
        for one, (vy, rr) in zip(singles, pairs):
            one.update(state(vy, rr, 30.0), 0.01, True)
    accel = np.array(loads)
    got = batch.at(accel)
    for i, one in enumerate(singles):
        assert got[0][i] == pytest.approx(one.at(loads[i])[0], rel=1e-12)
        assert got[1][i] == pytest.approx(one.at(loads[i])[1], rel=1e-12)
