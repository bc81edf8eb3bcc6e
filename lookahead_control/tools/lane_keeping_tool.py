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


"""Executable ``lane_keeping_stability``: the CG-compensated law's stability checks."""

from __future__ import annotations

from argparse import ArgumentParser
from dataclasses import replace
import json
import math
import os
from pathlib import Path
from typing import Any, Optional, Sequence

from lookahead_control.core.cli import (markdown_table, number, parser, run_tool, ToolError,
                                        write_json)
from lookahead_control.core.config import load_vehicle
from lookahead_control.core.lane_keeping import (CgCompensatedLaw, LaneKeepingParams,
                                                 settings_at_period)
from lookahead_control.core.lane_keeping_stability import (Certificate, certificate,
                                                           CERTIFICATE_SCHEDULES,
                                                           CERTIFICATE_WEIGHTS,
                                                           checked_delays, checked_speeds,
                                                           counted_checks, DELAY_STEP, DELAYS,
                                                           LOAD_POINTS, PERIOD, QRows,
                                                           sampled_checks, search_schedule,
                                                           weight_schedule)
from lookahead_control.core.params import ControllerParams, ParameterError, VehicleParams
from lookahead_control.tools.analysis_tools import add_envelope, check_envelope
import numpy as np


def stability_main(argv: Sequence[str] | None = None) -> int:
    """
    Print the varying-speed certificate and the robust check of the lane-keeping loop.

    :param argv: command-line arguments.
    :return: exit code (1 if either check fails).
    """
    p = parser('stability of the CG-compensated law (docs/lane_keeping.md): the Section 4 '
               'test on the closed loop with the integral and the acceleration terms of the '
               'law (V = x^T P(v) x, A_0^T P + P A_0 = -Q), and the sampled loop over '
               'plant mismatch, actuator lag and delay, with the law on exact states and on '
               'the estimate of the Kalman filter (lane_keeping.state_filter: kalman, the '
               'default; the exit code counts the checks of the loop that runs: with '
               'state_filter none the law on the measurements), and with the filter '
               'estimating the road curvature (no road_curvature received). The '
               'varying-speed certificate covers the law on exact states only; the sampled '
               'check covers the filter at frozen speeds', plot=False)
    add_envelope(p, 271, 'speeds checked from --v-min to --v-max (default 271)')
    p.add_argument('--natural-frequency', type=number(0.0, 100.0, low_open=True,
                                                      unit='rad/s'), default=None,
                   help='w_n of the y_v loop (default: that of the law)')
    p.add_argument('--a-error', type=number(0.0, 20.0, unit='m/s^2'), default=0.0,
                   metavar='M/S^2',
                   help='largest error of the a_x the law uses against the true dv_x/dt '
                   '(IMU bias, road grade, a differentiated speed) [m/s^2]; >= --a-max covers '
                   'acceleration_source zero (default 0)')
    p.add_argument('--integral-gain', type=number(0.0, 5.0, unit='1/s'), default=None,
                   help='k_i of the CG-error integral at and above '
                   "lane_keeping.integral_speed (below, the law's schedule down to "
                   'low_speed_integral_gain, capped at this; default: that of the law)')
    p.add_argument('--delays', type=number(0.0, 1.0, unit='s'), nargs='+',
                   default=list(DELAYS), metavar='S',
                   help="the plant's transport delays of the sampled checks (to 1 ms; a "
                   'fraction of the period acts as it is); a car with a long delay: the '
                   'delay and around it, with lane_keeping.filter_delay (and '
                   'delay_prediction) in --controller '
                   f'(default {" ".join(f"{d:g}" for d in DELAYS)})')
    p.add_argument('--period', type=number(0.0005, 0.5, unit='s'), default=None, metavar='S',
                   help="the sampled checks' period: how often the law answers, a "
                   "lane camera's frame period when each frame is answered (mode event; "
                   "0.05 for 20 Hz), the timer's in mode timer with a camera as fast, the "
                   "camera's frame period with a slower one (default: 1 / rate_hz of "
                   f'--controller in mode timer, else {PERIOD:g}: 100 Hz); in mode timer '
                   "every delay is also checked with the timer's period added (a frame "
                   'waits up to a tick)')
    p.add_argument('--controller', type=Path, default=None, metavar='YAML',
                   help='check the law the controller node would run with this params '
                   'file: its controller.* (d_v schedule) and lane_keeping.*; '
                   '--natural-frequency and --integral-gain override it (default: the '
                   'package defaults)')
    given_q = p.add_mutually_exclusive_group()
    given_q.add_argument('--search-q', type=Path, default=None, metavar='JSON',
                         help='search a speed schedule of the Q of the certificate for this '
                         'vehicle and law (Nelder-Mead, two knots at 14 and 24 m/s, or at '
                         "the envelope's thirds if it does not hold both, on 41 speeds), "
                         'write it to JSON and certify with it: for a vehicle or law the '
                         'shipped Q do not certify. About 0.05 s an evaluation, 0.2 s with '
                         "a cg_height, 0.5 s with a cg_height and an a_x error: the default's "
                         '2 to 16 minutes')
    given_q.add_argument('--q-knots', type=Path, default=None, metavar='JSON',
                         help="certify with the schedule of Q in this file (--search-q's "
                         'output) instead of the shipped ones')
    given_q.add_argument('--search-p', type=Path, default=None, metavar='JSON',
                         help='search the Lyapunov matrix P(v) itself, linear between 12 '
                         'speeds and the kinks, by semidefinite programming (cvxpy), write '
                         'it to JSON and certify with it: wider than any Q, and seconds to '
                         'a few minutes')
    given_q.add_argument('--p-knots', type=Path, default=None, metavar='JSON',
                         help="certify with the schedule of P in this file (--search-p's "
                         "output, or a --json report's P)")
    given_q.add_argument('--shipped-q-only', action='store_true',
                         help='certify with the shipped Q only: without it, where they do '
                         'not certify a loop stable at every frozen speed, a P(v) is '
                         'searched in the run as --search-p does (not written)')
    p.add_argument('--search-evaluations', type=number(1, 1_000_000, integer=True),
                   default=None, metavar='N',
                   help='the most bounds --search-q computes (default 2000)')
    p.add_argument('--search-p-knots', type=number(2, 1000, integer=True), default=None,
                   metavar='N',
                   help='uniform knots of the P(v) --search-p searches, beside the kinks '
                   '(default 12; more where P must bend fast, e.g. the k_i schedule of '
                   'low_speed_integral_gain: 80)')
    args = p.parse_args(argv)
    check_envelope(args)
    check_schedule_files(p, args)
    knots = read_knots(args.q_knots) if args.q_knots is not None else None
    lyapunov = read_knots(args.p_knots, 'P') if args.p_knots is not None else None
    overrides = {k: v for k, v in (('natural_frequency', args.natural_frequency),
                                   ('integral_gain', args.integral_gain)) if v is not None}
    period = PERIOD if args.period is None else args.period
    tick = 0.0      # mode timer: how old a frame can be when the timer answers it [s]
    vehicle = load_vehicle(args.vehicle)
    zero = False        # the law's a_x is 0 (acceleration_source: zero)
    if args.controller is None:
        loaded, controller = LaneKeepingParams(), ControllerParams()
    else:
        # as the node reads the file (its own check first: a name it does not have is
        # refused, not left at its default)
        from lookahead_control.tools.compare import load_law_settings
        # the node's safety limits are no part of the linear loop checked here; its
        # timing is (timer mode at rate_hz: another period than the checks' 10 ms)
        both = load_law_settings(args.controller, vehicle, ())
        loaded, controller = both.lane_keeping, both.controller
        if both.mode == 'timer':
            # the node answers every 1 / rate_hz (before dev-sc55 refused unless 100 Hz:
            # the checks sampled every PERIOD only), with the newest frame, which came up
            # to a tick before: that age is delay (dev-probe130: a 50 Hz timer 10 ms after
            # a 50 Hz camera's frames rang on the stiff, light car at 37 m/s with 50 ms,
            # 41.7 mrad, where the check at 50 ms without it held)
            tick = 1.0 / both.rate_hz
            if args.period is None:
                period = tick
            print(f'{args.controller}: mode timer at rate_hz {both.rate_hz:g}: the sampled '
                  f'checks run every {period:g} s'
                  + (' (a camera slower than the timer: --period its frame period)'
                     if args.period is None else ' (--period)')
                  + f', each delay also with the {tick:g} s a frame can wait for the timer')
        if both.law != 'cg_compensated':
            print(f'note: {args.controller} runs law {both.law} in the node; this checks '
                  "cg_compensated with the file's controller.* and lane_keeping.*")
        if both.acceleration_source == 'zero':
            # the node's law then takes a_x = 0 (before dev-probe55 the certificate was
            # given for an exact a_x: 'HOLDS' where it does not; until dev-sc32 as an
            # error up to --a-max, which also holds every a_hat within a_max of a)
            print(f'acceleration_source zero in {args.controller}: the law takes a_x = 0, '
                  'so the certificate is checked at a_hat = 0'
                  + (f' (--a-error {args.a_error:g} not used)' if args.a_error else ''))
            zero = True
            args.a_error = 0.0
        elif both.acceleration_source == 'differentiate' and args.a_error == 0.0:
            print(f'note: acceleration_source differentiate in {args.controller}: give the '
                  "differentiated speed's error in --a-error (checked here with an exact a_x)")
    try:
        settings = replace(loaded, **overrides)
    except ParameterError as err:       # with the file's (or the default) other settings
        given = ' '.join(f'--{k.replace("_", "-")} {v:g}' for k, v in overrides.items())
        raise ToolError(f'{given}: {err}') from err
    # the node's own checks across parameters (controller.reference): the law it refuses
    # is not certified
    CgCompensatedLaw(vehicle, controller, settings)
    if period > settings.max_gap:
        # every answer a time jump: the law restarts each time, no loop to check
        raise ToolError(f'a period of {period:g} s is above lane_keeping.max_gap = '
                        f'{settings.max_gap:g} s: the law restarts at every answer (a time '
                        'jump); answer faster or raise max_gap')
    from lookahead_control.tools.compare import LawSettings, settings_changes
    changed = settings_changes(LawSettings(controller, settings))
    print(f'settings: {args.controller or "the package defaults"}'
          + (f'; differing from the defaults: {", ".join(changed)}' if changed else ''))
    # the law cuts w_n at a slow answer period (frequency_lag, dev-sc56): every check
    # below is of the loop that runs at this period
    at_period = settings_at_period(settings, period)
    if at_period is not settings:
        floor = min(settings.low_speed_frequency, settings.natural_frequency)
        print(f'at an answer period of {period:g} s the law cuts w_n at '
              f'{at_period.natural_frequency:.4g} rad/s'
              + (' (its floor, low_speed_frequency)'
                 if at_period.natural_frequency <= floor else '')
              + f' (natural_frequency {settings.natural_frequency:g}, frequency_lag '
              f'{settings.frequency_lag:g} s): the checks below are of that loop')
    # the w_n the checks ran with at and above frequency_speed, for the JSON report
    frequency = (settings.natural_frequency, settings.frequency_lag, at_period.natural_frequency)
    settings = at_period
    # with cg_height the axles' stiffnesses move with a_x in the plant and the law: the
    # certificate then checks A(v, a, a_hat) on a grid of accelerations (dev-sc30; before,
    # a note said the load transfer was not covered)
    load_points = LOAD_POINTS if vehicle.cg_height > 0.0 else 0
    if args.search_q is not None:
        try:
            found = search_schedule(vehicle, controller, settings, args.v_min, args.v_max,
                                    args.a_max, args.a_error, load_points,
                                    evaluations=args.search_evaluations or 2000)
        except ImportError as err:      # scipy is a test dependency, not the node's
            raise ToolError('--search-q needs scipy (pip install scipy, or apt '
                            f'python3-scipy): {err}') from err
        except ValueError as err:
            raise ToolError(f'--search-q: {err}') from err
        knots = found.knots
        # what it was searched for, to redo it; written whole or not at all
        written = args.search_q.with_name(args.search_q.name + '.partial')
        write_json(written, {
            'knots': [[speed, [list(row) for row in q]] for speed, q in knots],
            'search_bound': found.found, 'start_bound': found.start,
            'evaluations': found.evaluations, 'interrupted': found.interrupted is not None,
            'searched_for': {'vehicle': args.vehicle and str(args.vehicle),
                             'controller': args.controller and str(args.controller),
                             'v_min': args.v_min, 'v_max': args.v_max, 'a_max': args.a_max,
                             'a_error': args.a_error, 'samples': 41,
                             'load_points': min(load_points, 5)}})
        os.replace(written, args.search_q)
        if found.interrupted is not None:
            # the best point so far is kept (--q-knots reads it), then the tool stops
            print(f'search interrupted after {found.evaluations} bounds on 41 speeds: the '
                  f'best schedule so far (bound {found.start:.4g} -> {found.found:.4g}) '
                  f'written to {args.search_q}', flush=True)
            raise found.interrupted
        print(f'searched a schedule of Q ({found.evaluations} bounds on 41 speeds): bound '
              f'{found.start:.4g} -> {found.found:.4g}; written to {args.search_q}; the '
              'certificate below is checked with it')
    if args.search_p is not None:
        lyapunov = search_p(args, vehicle, controller, settings, load_points, zero)
    for flag, path in (('--q-knots', args.q_knots), ('--p-knots', args.p_knots)):
        if path is not None:
            searched_note(flag, path, args, zero)
    try:
        cert = certificate(vehicle, controller, settings, args.v_min, args.v_max, args.a_max,
                           args.samples, a_error=args.a_error, load_points=load_points,
                           q_knots=knots, p_knots=lyapunov, a_hat_zero=zero)
    except np.linalg.LinAlgError as err:   # a given schedule's entries beyond precision
        raise ToolError(f'--{"q" if knots else "p"}-knots {args.q_knots or args.p_knots}: '
                        'the certificate could not be computed with this schedule: '
                        f'{err}') from err
    p_source = None if lyapunov is None else str(args.search_p or args.p_knots)
    searched_notes: list[str] = []
    if not cert.holds and cert.max_real_eig < 0.0 and knots is None and lyapunov is None \
            and not args.shipped_q_only:
        # the shipped Q are the Table 1 car's: a stable loop they do not certify may have
        # a P of its own (dev-sc32: 0.58 m with acceleration_source zero, 1.538 -> 0.323);
        # searched here since dev-sc33 (before, a note pointed to --search-p)
        found_p = fallback_p(vehicle, controller, settings, args, load_points, zero, cert,
                             searched_notes)
        if found_p is not None:
            lyapunov, cert = found_p
            p_source = 'searched in this run'
    # the delays to 1 ms, checked and printed as rounded (before dev-sc55 rounded to the
    # 10 ms period: at another period 20 ms were 0 or 50); mode timer: a frame waits up to
    # a tick for the timer, more delay (each end checked)
    asked, delays = checked_delays(args.delays, tick)
    moved = [d for d in args.delays if all(abs(d - c) > 1e-12 for c in asked)]
    if moved:
        print(f'--delays {" ".join(f"{d:.10g}" for d in moved)} rounded to '
              f'{DELAY_STEP * 1e3:g} ms: {", ".join(f"{d:g}" for d in asked)} s')
    # the sampled checks at the envelope's ends and the fixed speeds inside it
    at = checked_speeds(args.v_min, args.v_max)
    # state_filter none: the law acts on the measurements, the loop of the rows on exact
    # states; the Kalman rows are another controller's (before, they were counted: a
    # file with the filter off failed on a filter it does not run, dev-probe93)
    kalman = settings.state_filter == 'kalman'
    checks = sampled_checks(vehicle, controller, settings, delays, at, period)
    robust, filtered, estimated, frozen, frozen_estimated, approach = checks
    states = 'Kalman estimate' if kalman else 'exact states'
    unused = '' if kalman else ' (not counted: state_filter none)'
    # the test's value is proportional to (a_max, a_error): the largest factor on both
    # that it certifies (with a_error = 0: the largest |a_x|)
    factor = 1.0 / cert.between if cert.between > 0.0 else float('inf')
    if load_points and args.a_max > 0.0:
        # with the load transfer A is not affine in a_x and the value not proportional:
        # the factor on (a_max, a_error) by doubling, then bisection (before, bisected
        # over [0, 2] only: --a-max 0.5 said 0.999 where 1.6 held, dev-probe66)

        def holds(scale: float) -> bool:
            return certificate(vehicle, controller, settings, args.v_min, args.v_max,
                               args.a_max * scale, args.samples,
                               a_error=args.a_error * scale, load_points=load_points,
                               q_knots=knots, p_knots=lyapunov, a_hat_zero=zero).holds

        low, high = (1.0, 2.0) if cert.holds else (0.0, 1.0)
        while high < 64.0 and holds(high):
            low, high = high, 2.0 * high
        for _ in range(12):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if holds(middle) else (low, middle)
        factor = low
    # --a-max 0 (constant speed): no largest |a_x| to give (before: 'inf', dev-probe66)
    certified = args.a_max * factor if args.a_max > 0.0 else None
    grid_check = ('max eig Q^-1 (D^T P + P D + a P_v), D = A(v, a, a_hat) - A(v, 0, 0), on '
                  'the grid' if load_points else 'max eig Q^-1 (a P_v + a_hat M) on the grid')
    rows = [
        {'check': 'max Re eig A(v) over speed', 'value': cert.max_real_eig,
         'passes if': '< 0', 'holds': cert.max_real_eig < 0.0},
        {'check': grid_check, 'value': cert.max_norm,
         'passes if': '< 1', 'holds': cert.max_norm < 1.0},
        {'check': '... bounded between grid points', 'value': cert.between,
         'passes if': '< 1', 'holds': cert.between < 1.0},
        {'check': f'max spectral radius, {robust.cases} mismatch cases, exact states',
         'value': robust.max_radius, 'passes if': '< 1', 'holds': robust.holds},
        {'check': f'max spectral radius, {filtered.cases} mismatch cases, Kalman '
                  f'estimate{unused}',
         'value': filtered.max_radius, 'passes if': '< 1', 'holds': filtered.holds},
        {'check': f'max spectral radius, {estimated.cases} mismatch cases, Kalman estimate, '
                  f'curvature estimated{unused}', 'value': estimated.max_radius,
         'passes if': '< 1', 'holds': estimated.holds},
        {'check': f'max spectral radius, {frozen.cases} mismatch cases, {states}, '
                  'integral held (|y_cg| >= integral_band)', 'value': frozen.max_radius,
         'passes if': '< 1', 'holds': frozen.holds},
        {'check': f'max spectral radius, {frozen_estimated.cases} mismatch cases, Kalman '
                  f'estimate, curvature estimated, integral held{unused}',
         'value': frozen_estimated.max_radius, 'passes if': '< 1',
         'holds': frozen_estimated.holds},
    ]
    if certified is not None:
        rows.insert(3, {'check': 'largest certified |a_x| [m/s^2]' if args.a_error == 0.0
                        else f'largest certified |a_x| with a_error x{factor:.3g} [m/s^2]',
                        'value': certified, 'passes if': f'>= {args.a_max:g}',
                        'holds': certified >= args.a_max})
    if approach is not None:
        rows.append({'check': f'max spectral radius, {approach.cases} mismatch cases, '
                              f'{states}, approach (CG offset clipped, integral held)',
                     'value': approach.max_radius, 'passes if': '< 1',
                     'holds': approach.holds})
    kinks = (f'kinks at {", ".join(f"{k:.2f}" for k in cert.kinks)} m/s, both sides'
             if cert.kinks else 'no kinks')
    # every grid point that is not the uniform grid's is named (dev-probe67: "7 speeds
    # (kinks at 10.78, 21.43, 30.00 m/s)" with --samples 2 left out Q's knots)
    if cert.knots:
        kinks += (f'; the knots of {"Q" if lyapunov is None else "P"} at '
                  f'{", ".join(f"{k:g}" for k in cert.knots)} m/s')
    if cert.load_kinks:
        kinks += (f'; {cert.load_kinks} more where d_v leaves its floor under an '
                  "acceleration's loads")
    speeds = f'{cert.speeds} speed' + ('' if cert.speeds == 1 else 's')
    weight = cert.weight
    if knots is not None:
        weight = (f'given ({args.search_q or args.q_knots}: knots at '
                  f'{", ".join(f"{speed:g}" for speed, _ in knots)} m/s)')
    elif lyapunov is not None:
        source = ('searched in this run (not written' if p_source == 'searched in this run'
                  else f'given ({p_source}')
        weight = (f'-(A_0^T P + P A_0) of the P {source}: linear in v_x between '
                  f'{len(lyapunov)} knot{"" if len(lyapunov) == 1 else "s"})')
    elif weight in CERTIFICATE_SCHEDULES:         # a speed schedule of Q (dev-sc31)
        listed = ', '.join(f'{speed:g}' for speed, _ in CERTIFICATE_SCHEDULES[weight])
        weight += f' (linear in v_x between its knots at {listed} m/s)'
    error = ('the law a_x 0' if zero else
             f'error of the law a_x <= {cert.a_error:g} m/s^2')
    print(f'envelope: v_x in [{cert.v_min:g}, {cert.v_max:g}] m/s, |a_x| <= '
          f'{cert.a_max:g} m/s^2, {error}; '
          f'checked at {speeds} ({kinks}) with Q {weight}; worst value at '
          f'{cert.max_norm_speed:.2f} m/s; sampled checks at '
          f'{", ".join(f"{v:g}" for v in at)} m/s every {period:g} s, plant delays '
          f'{", ".join(f"{d:g}" for d in delays)} s; worst mismatch case {robust.worst} (exact '
          f'states), {filtered.worst} (Kalman estimate)')
    print('the certificate covers the law on exact states at varying speed; the sampled '
          'check covers the law on the estimate of the Kalman filter at frozen speeds'
          if kalman else 'the certificate covers the law on exact states at varying speed, '
          'the sampled check at frozen speeds (state_filter none: the law acts on the '
          'measurements)')
    notes = exact_inverse_notes(settings)
    if settings.force_feedforward > 0.0:
        notes.append(f'lane_keeping.force_feedforward = {settings.force_feedforward:g}: the '
                     "filter's force estimates in the drift term; the certificate and the "
                     'robust check on exact states have no estimate (no filter): the '
                     'checks with the filter contain it')
    if lyapunov is not None and cert.max_real_eig < 0.0 and math.isinf(cert.between):
        # dev-probe69: only 'inf' and the worst finite value's speed were printed
        notes.append(f'Q(v) = -(A_0^T P + P A_0) of the P given is not positive definite '
                     f'at {cert.max_norm_speed:.4g} m/s: V = x^T P x does not fall there '
                     'even at a constant speed, so this P is no certificate')
    notes += searched_notes
    if not cert.holds and cert.max_real_eig < 0.0 and knots is None and lyapunov is None \
            and args.shipped_q_only:
        notes.append('no shipped Q certifies this loop: without --shipped-q-only (or with '
                     '--search-p OUT.json) a P(v) is searched for this vehicle and law '
                     '(cvxpy; seconds to two minutes)')
    if vehicle.cg_height > 0.0:
        # the law's stiffnesses then move with its a_x (core/params.py, loaded_vehicle)
        notes.append(f'vehicle.cg_height = {vehicle.cg_height:g} m: the certificate has '
                     "each axle's stiffness at its load, the plant's under a_x and the "
                     f"law's under its a_x, checked at {load_points} accelerations (not "
                     'affine in a_x: the largest certified |a_x| is bisected); the sampled '
                     'checks are at frozen speed, a_x 0: static loads')
    if not kalman:
        notes.append(f'lane_keeping.state_filter = {settings.state_filter}: the law acts on '
                     'the measurements; the rows "Kalman estimate" are the law with the '
                     'filter: reported, not counted in the verdict; the integral held and '
                     'the approach are checked on exact states; without road_curvature the '
                     'curvature is estimated by a filter of its own, not checked here')
    if settings.delay_prediction:
        notes.append("lane_keeping.delay_prediction: the law acts on the filter's estimate "
                     'predicted across filter_delay; the row "exact states" is the law '
                     'without the filter and its prediction: reported, not counted in the '
                     'verdict')
    for note in notes:
        print(note)
    print(markdown_table(rows))
    verdict = cert.holds and all(c.holds for c in counted_checks(settings, checks))
    print(f'certificate {"HOLDS" if cert.holds else "DOES NOT HOLD"}; robust check '
          f'{"HOLDS" if robust.holds else "DOES NOT HOLD"}'
          f'{" (not counted: delay_prediction)" if settings.delay_prediction else ""}; '
          'robust check with the filter '
          f'{"HOLDS" if filtered.holds else "DOES NOT HOLD"}{unused}; with the curvature '
          f'estimated {"HOLDS" if estimated.holds else "DOES NOT HOLD"}'
          f'{" (without the exact inverse)" if settings.exact_inverse > 0.0 else ""}'
          f'{unused}; with the integral '
          f'held {"HOLDS" if frozen.holds else "DOES NOT HOLD"}, and with the curvature '
          f'estimated {"HOLDS" if frozen_estimated.holds else "DOES NOT HOLD"}'
          f'{" (without the exact inverse)" if settings.exact_inverse > 0.0 else ""}'
          f'{unused}'
          + ('' if approach is None else
             f'; in the approach {"HOLDS" if approach.holds else "DOES NOT HOLD"}'))
    if args.json:
        write_json(args.json, {'certificate': cert._asdict(),
                               'q': q_used(cert.weight, knots, args, cert.v_min,
                                           lyapunov, p_source),
                               'law_a_x_zero': zero, 'verdict': verdict,
                               'kalman_rows_counted': kalman,
                               'sampled_period_s': period, 'plant_delays_s': list(delays),
                               'natural_frequency': frequency[0],
                               'frequency_lag_s': frequency[1],
                               'frequency_cap_at_period': frequency[2],
                               'robust': robust._asdict(),
                               'robust_filtered': filtered._asdict(),
                               'robust_curvature_estimated': estimated._asdict(),
                               'robust_integral_held': frozen._asdict(),
                               'robust_integral_held_curvature_estimated':
                                   frozen_estimated._asdict(),
                               'robust_approach': (None if approach is None
                                                   else approach._asdict()),
                               'rows': rows, 'notes': notes})
    return 0 if verdict else 1


def exact_inverse_notes(settings: LaneKeepingParams) -> list[str]:
    """
    Return what the checks leave out of ``lane_keeping.exact_inverse`` (none when it is 0).

    With a ``road_curvature`` preview the exact inverse's model is driven by the preview,
    the speed and the compliance estimate alone: an exogenous reference, so every check
    holds for it as for 0. Without one the model runs along the filter's curvature
    estimate, a state of the loop; the rows 'curvature estimated' take the law's terms in
    the estimate as static gains (``curvature_gain``, ``rate_gain``) and do not contain
    the model's own dynamics (its 0.18-damped mode at 37 m/s).

    :param settings: the law's settings.
    :return: one line per note.
    """
    if settings.exact_inverse <= 0.0:
        return []
    return [f'lane_keeping.exact_inverse = {settings.exact_inverse:g}: with road_curvature '
            'its model is an exogenous reference (the checks hold for it as for 0); the rows '
            "'curvature estimated' take the law's terms in the estimated curvature as "
            "static gains and leave out its model's dynamics along the estimate: that loop "
            'is not checked']


def check_schedule_files(p: ArgumentParser, args: Any) -> None:
    """
    Refuse, before any work, the schedule options that would fail late or lose a file.

    :param p: the parser (its one-line error).
    :param args: the parsed arguments.
    """
    if args.search_evaluations is not None and args.search_q is None:
        p.error('--search-evaluations: only with --search-q')
    if args.search_p_knots is not None and args.search_p is None:
        p.error('--search-p-knots: only with --search-p')
    for flag, path in (('--search-q', args.search_q), ('--q-knots', args.q_knots),
                       ('--search-p', args.search_p), ('--p-knots', args.p_knots)):
        # dev-probe68: --json overwrote the schedule file it named
        if path is not None and args.json is not None and \
                path.resolve() == args.json.resolve():
            p.error(f'--json {args.json}: the same file as {flag}')
    flag, out = (('--search-q', args.search_q) if args.search_q is not None else
                 ('--search-p', args.search_p))
    if out is None:
        return
    # dev-probe68: a directory or an unwritable path failed only after the search
    if out.is_dir():
        p.error(f'{flag} {out}: is a folder')
    folder = out.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        p.error(f'{flag} {out}: {folder} is not a folder this user may write in')


def search_p(args: Any, vehicle: VehicleParams, controller: ControllerParams,
             settings: LaneKeepingParams, load_points: int,
             zero: bool) -> tuple[tuple[float, QRows], ...]:
    """
    Search a schedule of ``P`` (``--search-p``), write it with its provenance, return it.

    :param args: the parsed arguments (envelope, bounds, the output path).
    :param vehicle: the design vehicle.
    :param controller: d_v schedule.
    :param settings: the law's settings.
    :param load_points: the certificate's accelerations (0: static stiffnesses).
    :param zero: the law's ``a_x`` is 0.
    :return: the knots found.
    :raises ToolError: without cvxpy, or no ``P`` found.
    """
    try:
        from lookahead_control.core.lyapunov_search import search_lyapunov
        found = search_lyapunov(vehicle, controller, settings, args.v_min, args.v_max,
                                args.a_max, args.a_error, load_points,
                                knots=args.search_p_knots or 12, a_hat_zero=zero)
    except ImportError as err:      # cvxpy is the search's alone, not the node's
        raise ToolError('--search-p needs cvxpy with its Clarabel solver (pip install '
                        f'cvxpy clarabel): {err}') from err
    except ValueError as err:
        # the knots only where more of them can help (dev-probe70: an unstable loop
        # was told to try more knots)
        more = ('' if 'try more knots' not in str(err) else
                f' (--search-p-knots, now {args.search_p_knots or 12})')
        raise ToolError(f'--search-p: {err}{more}') from err
    # what it was searched for, to redo it; written whole or not at all
    written = args.search_p.with_name(args.search_p.name + '.partial')
    write_json(written, {
        'knots': [[speed, [list(row) for row in m]] for speed, m in found.knots],
        'matrix': 'P', 'sample_bound': found.target, 'solves': found.solves,
        'samples': found.samples,
        'searched_for': {'vehicle': args.vehicle and str(args.vehicle),
                         'controller': args.controller and str(args.controller),
                         'v_min': args.v_min, 'v_max': args.v_max, 'a_max': args.a_max,
                         'a_error': args.a_error, 'law_a_x_zero': zero,
                         'load_points': load_points, 'knots': args.search_p_knots or 12}})
    os.replace(written, args.search_p)
    print(f'searched P(v) linear between {len(found.knots)} knots ({found.solves} '
          f'semidefinite programs on {found.samples} sample speeds): value {found.target:.4g} '
          f'there; written to {args.search_p}; the certificate below is checked with it')
    return found.knots


def fallback_p(vehicle: VehicleParams, controller: ControllerParams,
               settings: LaneKeepingParams, args: Any, load_points: int, zero: bool,
               shipped: Certificate,
               notes: list[str]) -> Optional[tuple[tuple[tuple[float, QRows], ...],
                                                   Certificate]]:
    """
    Search ``P(v)`` for a loop the shipped ``Q`` do not certify; return it if it does better.

    The shipped ``Q`` were searched for the Table 1 car: for another car or law the
    certificate may exist and they miss it. The search (:func:`search_lyapunov`, as
    ``--search-p`` with 12 knots) gives a ``P`` that the certificate then checks on its
    own grid, so the verdict is the certificate's, whichever way ``P`` was found.

    :param vehicle: the design vehicle.
    :param controller: d_v schedule.
    :param settings: the law's settings.
    :param args: the parsed arguments (the envelope, ``--samples``).
    :param load_points: the certificate's accelerations (0: static stiffnesses).
    :param zero: the law's ``a_x`` is 0.
    :param shipped: the certificate with the shipped ``Q``.
    :param notes: the report's notes, appended to (why there is no ``P``, or which won).
    :return: the knots and their certificate, or None (no cvxpy, none found, or not
        better than the shipped ``Q``).
    """
    print(f'the shipped Q do not certify this loop (bound {shipped.between:.4g}): searching '
          'P(v) for it (--shipped-q-only skips this; --search-p OUT.json writes it)',
          flush=True)
    # none at --a-max: one at a smaller envelope may still certify more than the shipped
    # Q do (dev-probe72: 0.58 m, a_x 0, --a-max 12: none at 12, the shipped Q certified
    # 2.3 m/s^2 where the P of 3.5 m/s^2 certifies 10.8)
    scales = (1.0, 0.5, 0.25, 0.125) if args.a_max > 0.0 else (1.0,)
    for scale in scales:
        at = args.a_max * scale
        try:
            from lookahead_control.core.lyapunov_search import search_lyapunov
            found = search_lyapunov(vehicle, controller, settings, args.v_min, args.v_max,
                                    at, args.a_error * scale, load_points, a_hat_zero=zero)
        except ImportError as err:          # cvxpy is the search's alone, not the node's
            notes.append('no shipped Q certifies this loop, and no P(v) could be searched: '
                         f'that needs cvxpy with its Clarabel solver ({err})')
            return None
        except ValueError as err:
            if 'meets the test' in str(err) and scale != scales[-1]:
                print(f'no P(v) on 12 knots meets the test at |a_x| {at:g} m/s^2: searching '
                      f'one at {0.5 * at:g}', flush=True)
                continue
            notes.append(f'no shipped Q certifies this loop, nor a P(v) searched on 12 '
                         f'knots: {err} (--search-p OUT.json --search-p-knots N)')
            return None
        break
    cert = certificate(vehicle, controller, settings, args.v_min, args.v_max, args.a_max,
                       args.samples, a_error=args.a_error, load_points=load_points,
                       p_knots=found.knots, a_hat_zero=zero)
    where = ('' if scale == 1.0 else
             f', searched at |a_x| {at:g} m/s^2 (none met the test at {args.a_max:g})')
    if not cert.between < shipped.between:
        notes.append(f'a P(v) searched on 12 knots{where} gave {cert.between:.4g} on the '
                     f'full grid, no better than the shipped Q ({shipped.between:.4g}): not '
                     'used')
        return None
    notes.append(f'the shipped Q do not certify this loop ({shipped.between:.4g}); the '
                 f'verdict is that of a P(v) searched in this run{where}: bound '
                 f'{cert.between:.4g}, value {found.target:.4g} at its {found.samples} sample '
                 'speeds; --search-p OUT.json writes it; --p-knots reads that file or the '
                 '--json report back')
    return found.knots, cert


def q_used(name: str, knots: Optional[tuple[tuple[float, QRows], ...]], args: Any,
           v_min: float, lyapunov: Optional[tuple[tuple[float, QRows], ...]] = None,
           p_source: Optional[str] = None) -> dict[str, Any]:
    """
    Return which ``Q`` (or ``P``) gave the verdict, for the JSON report (to redo it).

    :param name: the certificate's ``weight``.
    :param knots: the schedule given or searched (None: the shipped ones).
    :param args: the parsed arguments.
    :param v_min: the envelope's lower speed (a constant ``Q``'s one knot).
    :param lyapunov: a schedule of ``P`` given or searched (``--p-knots``,
        ``--search-p``, or in the run where the shipped ``Q`` do not hold).
    :param p_source: where ``lyapunov`` came from (its file, or ``searched in this run``).
    :return: its name, source, which matrix the knots hold and the knots.
    """
    if lyapunov is not None:
        return {'name': name, 'source': p_source, 'matrix': 'P',
                'knots': [[speed, [list(row) for row in m]] for speed, m in lyapunov]}
    if knots is not None:
        source = str(args.search_q or args.q_knots)
    elif name in CERTIFICATE_SCHEDULES:
        source, knots = 'shipped', CERTIFICATE_SCHEDULES[name]
    else:
        source, knots = 'shipped', ((v_min, CERTIFICATE_WEIGHTS[name]),)
    return {'name': name, 'source': source, 'matrix': 'Q',
            'knots': [[speed, [list(row) for row in q]] for speed, q in knots]}


def searched_note(flag: str, path: Path, args: Any, zero: bool) -> None:
    """
    Print what a schedule file was searched for where it differs from this check.

    A file used for another vehicle, law or envelope still gives a valid verdict for
    this one (any ``Q > 0``, any ``P`` is a test), but one that may not hold: said, so
    that a DOES NOT HOLD is not a puzzle (dev-probe70).

    :param flag: ``--q-knots`` or ``--p-knots``.
    :param path: the file (read already by :func:`read_knots`).
    :param args: the parsed arguments.
    :param zero: the law's ``a_x`` is 0 in this check.
    """
    try:
        searched = json.loads(path.read_text(encoding='utf-8')).get('searched_for')
    except (OSError, ValueError, AttributeError):
        return
    if not isinstance(searched, dict):
        return
    here = {'vehicle': args.vehicle and str(args.vehicle),
            'controller': args.controller and str(args.controller), 'v_min': args.v_min,
            'v_max': args.v_max, 'a_max': args.a_max, 'a_error': args.a_error,
            'law_a_x_zero': zero}
    differ = [f'{key} {searched[key]!r} (here {value!r})' for key, value in here.items()
              if key in searched and searched[key] != value]
    if differ:
        print(f'note: {flag} {path} was searched for {", ".join(differ)}: the verdict '
              'below is for this check')


def read_knots(path: Path, symbol: str = 'Q') -> tuple[tuple[float, QRows], ...]:
    """
    Return the speed schedule of ``Q`` (or ``P``) in a file written by ``--search-q``.

    Also this tool's ``--json`` report: its ``"q"``, the ``Q`` or ``P`` that gave the
    verdict (a ``P`` searched in the run included).

    :param path: the JSON file (``{"knots": [[speed, [5 rows of 5]], ...]}``).
    :param symbol: ``Q`` (``--q-knots``, ``--search-q``'s file) or ``P`` (``--p-knots``,
        ``--search-p``'s).
    :return: the knots, checked as the certificate checks them.
    :raises ToolError: the file cannot be read or does not hold such a schedule.
    """
    flag, writer = f'--{symbol.lower()}-knots', f'--search-{symbol.lower()}'
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
        if isinstance(data, dict) and 'knots' not in data and \
                isinstance(data.get('q'), dict):
            data = data['q']        # this tool's --json report: the Q or P it used
        held = data.get('matrix', 'Q')          # --search-q's files before dev-sc32: Q
        if held != symbol:                      # a P file given as Q's, or Q's as P's
            raise ValueError(f'it holds a schedule of {held!r}, not of {symbol}'
                             + ('' if 'matrix' in data else ' (a file without "matrix": '
                                '"P" holds Q, as --search-q writes them)'))
        knots = tuple((speed, tuple(tuple(row) for row in q)) for speed, q in data['knots'])
        entries = [w for _, q in knots for row in q for w in row]
        if not all(isinstance(w, (int, float)) and not isinstance(w, bool) for w in entries):
            raise ValueError(f"{symbol}'s entries must be numbers")
        for speed, q in weight_schedule(knots, symbol):
            if np.linalg.cond(q) > 1e12:     # the Lyapunov solves lose every digit
                raise ValueError(f'{symbol} at {speed:g} m/s has a condition number of '
                                 f'{np.linalg.cond(q):.3g}: above 1e12')
    except OSError as err:
        raise ToolError(f'{flag} {path}: {err.strerror or err}') from err
    except (ValueError, TypeError, KeyError, AttributeError) as err:
        raise ToolError(f'{flag} {path}: not a schedule of {symbol} as {writer} writes it '
                        f'({{"knots": [[speed, [5 rows of 5]], ...]}}): {err}') from err
    return knots


def stability_tool() -> int:
    """Entry point of ``lane_keeping_stability``."""
    return run_tool(stability_main)


if __name__ == '__main__':
    import sys
    sys.exit(stability_tool())
