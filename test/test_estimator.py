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
from lookahead_control.core.estimator import ComplianceEstimator
from lookahead_control.core.params import VehicleParams
import numpy as np
import pytest

VEHICLE = VehicleParams()


def estimator(time_constant=0.5, filter_time=0.3, prior=0.5, ratio=3.0):
    return ComplianceEstimator(VEHICLE, time_constant, filter_time, prior, ratio)


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
