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

"""The Section 4 certificate and the metrics helpers."""

import math

from lookahead_control.analysis.metrics import damping_from_overshoot, step_metrics
from lookahead_control.core.params import VehicleParams
from lookahead_control.core.stability import certificate, lyapunov, lyapunov_derivative
from lookahead_control.core.zero_dynamics import system_matrix
import numpy as np
from numpy.testing import assert_allclose
import pytest

VEHICLE = VehicleParams()


def test_lyapunov_solution_solves_the_equation():
    a = system_matrix(VEHICLE, 25.0, 17.47)
    p = lyapunov(a, np.eye(2))
    assert_allclose(a.T @ p + p @ a, -np.eye(2), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(p) > 0)


def test_lyapunov_derivative_matches_finite_difference():
    for v in (12.0, 25.0, 36.0):
        h = 1e-5
        p_plus, _ = lyapunov_derivative(VEHICLE, v + h)
        p_minus, _ = lyapunov_derivative(VEHICLE, v - h)
        _, p_v = lyapunov_derivative(VEHICLE, v)
        assert_allclose(p_v, (p_plus - p_minus) / (2 * h), rtol=1e-6, atol=1e-9)


def test_certificate_holds_on_the_paper_envelope():
    cert = certificate(VEHICLE)
    assert cert.holds_norm and cert.holds_gershgorin
    assert cert.d_v_max == pytest.approx(40.14, abs=0.01)
    # same order as the paper's reported values (0.477, -0.4502, -0.8133, 0.0395)
    assert 0.3 < cert.max_norm < 1.0
    assert cert.b11 + cert.r < 0 and cert.b22 + cert.r < 0
    # the eigenvalue test is the sharp one; the disc test is its bound
    assert cert.max_eig_b <= max(cert.b11, cert.b22) + cert.r + 1e-12


def test_certificate_fails_for_violent_acceleration():
    cert = certificate(VEHICLE, a_max=12.0, samples=201)
    assert not cert.holds_norm
    assert cert.max_norm == pytest.approx(certificate(VEHICLE, samples=201).max_norm
                                          * 12.0 / 3.5)


def test_step_metrics_of_a_known_second_order_response():
    zeta, w = 0.3, 4.0
    t = np.linspace(0, 15, 15001)
    wd = w * math.sqrt(1 - zeta ** 2)
    y = 1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2)
                                     * np.sin(wd * t))
    m = step_metrics(t, 2.0 * y, 0.0)
    assert m.final == pytest.approx(2.0, rel=1e-6)
    assert m.overshoot == pytest.approx(math.exp(-zeta * math.pi
                                                 / math.sqrt(1 - zeta ** 2)), rel=1e-3)
    assert m.damping_ratio == pytest.approx(zeta, rel=1e-3)
    assert m.settling_time == pytest.approx(3.0, rel=0.15)   # ~4 / (zeta w) = 3.3 s
    assert math.isnan(damping_from_overshoot(0.0))
