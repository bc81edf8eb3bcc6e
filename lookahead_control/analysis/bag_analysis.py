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

"""
Metrics of recorded runs: time series per control step, and one table row per bag.

No ROS here. A step is a lateral-error stamp. Errors come from the simulator's ground
truth where the bag has it, else from the measurements (``y_cg = y_s - d eps_r``); the
look-ahead distance and reference from the controller's debug topic, else from the
controller re-run on the bag's inputs; latency is the receive time of the steering
minus that of the lateral error it answers, both as the recorder saw them.

Nothing is silently assumed: parameters a bag does not carry are the defaults, and the
row's ``notes`` say so; gaps in an input, answers recorded before their question (the
recorder's receive order, which is no latency) and too short runs are named there, and a
metric that does not apply is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, Optional

from lookahead_control.analysis.diagnostics_summary import (DiagnosticsSummary, summarize,
                                                            summary_note)
from lookahead_control.analysis.metrics import run_metrics
from lookahead_control.bags.run_data import rerun_law, RunData, Samples, scenario_text
from lookahead_control.core.control_law import cg_error_from
from lookahead_control.core.controller import LAW_NAMES
from lookahead_control.core.params import ControllerParams, VehicleParams
import numpy as np
import numpy.typing as npt
import yaml

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
SERIES = ('y_cg', 'eps_r', 'rho', 'v_x', 'd_v', 'y_ref', 'error', 'steering_cmd', 'steering')
STATE_FIELDS = ('s', 'y_cg', 'eps_r', 'v_y', 'r', 'v_x')
GAP_FACTOR = 5.0
GAP_MIN = 0.05
MIN_LATENCY_SAMPLES = 10
MIN_P99_SAMPLES = 100
LAW_CHANNELS = ('d_v', 'y_ref', 'error')


@dataclass(frozen=True)
class RunSeries:
    """
    One value per control step.

    :param time: step stamps from the first [s].
    :param channels: the arrays named in :data:`SERIES` (``steering``, the wheel angle
        the plant reports, is NaN where the bag has no ground truth, ``steering_cmd``
        NaN at unanswered steps).
    :param latency: steering receive minus lateral-error receive, per answered step [s].
    :param unanswered: steps without a recorded steering command.
    """

    time: Array
    channels: dict[str, Array]
    latency: Array
    unanswered: int


def _latest(stamps_of: IntArray, stamps: IntArray) -> IntArray:
    """
    Return, for each stamp, the newest sample stamped at or before it.

    :param stamps_of: the samples' stamps, in the order they came.
    :param stamps: sorted stamps to look up.
    :return: the index of the sample (of those stamped alike, the last to come), -1 for
        none.
    """
    if not stamps_of.size:
        return np.full(stamps.shape, -1, dtype=np.int64)
    by_stamp = np.argsort(stamps_of, kind='stable')
    at = np.searchsorted(stamps_of[by_stamp], stamps, side='right') - 1
    return np.where(at >= 0, by_stamp[np.maximum(at, 0)], -1)


def _exact(stamps_of: IntArray, stamps: IntArray) -> IntArray:
    """Return, for each stamp, the last sample stamped exactly so (-1 for none)."""
    found = _latest(stamps_of, stamps)
    if stamps_of.size:
        found[stamps_of[np.maximum(found, 0)] != stamps] = -1
    return found


def _take(values: Optional[Array], found: IntArray, default: float = math.nan) -> Array:
    """Return ``values[found]`` where found (>= 0), else the default."""
    if values is None or not values.size:
        return np.broadcast_to(np.asarray(default, dtype=float), found.shape).copy()
    return np.where(found >= 0, values[np.maximum(found, 0)], default)


def _forward_fill(values: Array | list[float]) -> Array:
    """Replace each NaN by the last value before it (0 before the first value)."""
    out = np.array(values, dtype=float)
    index = np.where(np.isnan(out), 0, np.arange(out.size))
    np.maximum.accumulate(index, out=index)
    return np.nan_to_num(out[index], nan=0.0)


def run_series(run: RunData) -> RunSeries:
    """
    Return the per-step series of a run.

    A ground-truth or debug value that is missing or NaN counts as not recorded: the
    measured or re-computed one is used, else the last value before it.

    :param run: the run read from a bag.
    :return: the series.
    :raises ValueError: no lateral-error message with yaw and velocity to go with it.
    """
    empty = Samples.empty()
    lateral = run.inputs.get('lateral_error', empty)
    yaw, velocity = run.inputs.get('yaw', empty), run.inputs.get('velocity', empty)
    curvature = run.inputs.get('road_curvature', empty)
    stamps = np.unique(lateral.stamp_ns)
    yaw_at, velocity_at = _latest(yaw.stamp_ns, stamps), _latest(velocity.stamp_ns, stamps)
    keep = (yaw_at >= 0) & (velocity_at >= 0)
    if not keep.any():
        empty_roles = [role for role, samples in (('yaw', yaw), ('velocity', velocity))
                       if not len(samples)]
        why = (f' (no {" and no ".join(empty_roles)} messages: is the topic missing or '
               'named otherwise? --topic ROLE=NAME)' if empty_roles else
               ' (none stamped at or before a lateral error)')
        raise ValueError(f'{run.bag}: no lateral error with yaw and velocity to go with '
                         f'it{why}')
    kept, yaw_at, velocity_at = stamps[keep], yaw_at[keep], velocity_at[keep]
    lateral_at = _latest(lateral.stamp_ns, kept)
    truth_at = _exact(run.truth.stamp_ns, kept)

    def truth(name: str, otherwise: Array | float) -> Array:
        # not recorded at a stamp, or recorded non-finite (told by truth_not_finite: an
        # inf eps_r gave inf errors, a yaw excursion of 1.8e308 and RuntimeWarnings,
        # dev-probe96): the measurements stand in
        recorded = _take(run.truth.values.get(name), truth_at)
        return np.where(np.isfinite(recorded), recorded, otherwise)

    channels: dict[str, Array] = {}
    channels['eps_r'] = truth('eps_r', yaw.values['relative_yaw'][yaw_at])
    channels['y_cg'] = truth('y_cg', cg_error_from(
        lateral.values['value'][lateral_at], channels['eps_r'],
        lateral.values['distance'][lateral_at]))
    channels['rho'] = truth('rho', _take(curvature.values.get('rho'),
                                         _latest(curvature.stamp_ns, kept), 0.0))
    channels['v_x'] = velocity.values['v_x'][velocity_at]
    debug_at = _exact(run.debug.stamp_ns, kept)
    for name in LAW_CHANNELS:
        channels[name] = _take(run.debug.values.get(name), debug_at)
    missing = {name: np.isnan(channels[name]) for name in LAW_CHANNELS}
    if any(gaps.any() for gaps in missing.values()):
        # not recorded (no debug topic, or a recorder that subscribed to it late): the
        # controller re-run on the bag's inputs
        law_stamps, output = rerun_law(run)
        law_at = _exact(law_stamps, kept)
        for name, gaps in missing.items():
            channels[name] = np.where(gaps, _take(getattr(output, name), law_at),
                                      channels[name])
    steering_at = _exact(run.steering.stamp_ns, kept)
    channels['steering_cmd'] = _take(run.steering.values.get('angle'), steering_at)
    channels['steering'] = truth('steering', math.nan)
    # latency: from the arrival of the lateral error nearest to the answer used (the last
    # of its stamp): one stamp can arrive more than once (re-sent, or two runs in a bag),
    # and the recorder may receive an answer before its question
    answered = steering_at >= 0
    answer_recv = run.steering.recv_ns[steering_at[answered]]
    by = np.lexsort((lateral.recv_ns, lateral.stamp_ns))
    stamp_sorted, recv_sorted = lateral.stamp_ns[by], lateral.recv_ns[by]
    lo = np.searchsorted(stamp_sorted, kept[answered], side='left')
    hi = np.searchsorted(stamp_sorted, kept[answered], side='right')
    received = recv_sorted[lo]
    for i in np.nonzero(hi - lo > 1)[0].tolist():   # a stamp that arrived more than once
        arrivals = recv_sorted[lo[i]:hi[i]]
        received[i] = arrivals[int(np.argmin(np.abs(arrivals - answer_recv[i])))]
    latency = ((answer_recv - received) * 1e-9).astype(float)
    # the commands and the plant's wheel angle are recorded values: a missing one stays
    # missing (NaN; a recorder drop is no hold, and before the first answer is no 0); the
    # rest carry the last value
    filled = {name: (channels[name] if name in ('steering', 'steering_cmd') else
                     _forward_fill(channels[name])) for name in SERIES}
    return RunSeries((kept - kept[0]) * 1e-9, filled, latency, int((~answered).sum()))


def recorder_drops(run: RunData) -> Optional[int]:
    """Return the messages the recorder lost, if it counted them."""
    text = run.description.get('lookahead_control/recorder')
    if not text:
        return None
    report = yaml.safe_load(text) or {}
    return int(sum((entry or {}).get('dropped') or 0 for entry in report.values()))


def input_gaps(run: RunData, arrival: bool = True) -> dict[str, tuple[float, float]]:
    """
    Return the largest gap of each input and of the steering, in stamps or in arrival.

    A gap is a step between consecutive stamps, or between consecutive receive times
    (a stalled publisher or link: the stamps may be contiguous), longer than
    :data:`GAP_FACTOR` times the topic's median step and than :data:`GAP_MIN`.

    :param run: the run.
    :param arrival: also look at receive times (not for a lockstep simulation, whose
        plant waits for the controller: a stall there delays no step).
    :return: ``'<role> (stamps)'`` or ``'<role> (arrival)'`` -> ``(gap [s], its start
        [s] from the first lateral-error stamp or receive time)``, only where there is
        a gap.
    """
    lateral = run.inputs.get('lateral_error', Samples.empty())
    origins = ((int(lateral.stamp_ns.min()), int(lateral.recv_ns.min())) if len(lateral)
               else (0, 0))
    out = {}
    for role, samples in (*run.inputs.items(), ('steering', run.steering)):
        kinds = (('stamps', samples.stamp_ns, origins[0]),
                 ('arrival', samples.recv_ns, origins[1]))
        for kind, times, origin in kinds[:2 if arrival else 1]:
            ordered = np.sort(times)        # (np.unique hashes: seconds on long bags)
            if ordered.size:
                ordered = ordered[np.concatenate([[True], ordered[1:] != ordered[:-1]])]
            if ordered.size < 3:
                continue
            steps = np.diff(ordered) * 1e-9
            limit = max(GAP_FACTOR * float(np.median(steps)), GAP_MIN)
            worst = int(np.argmax(steps))
            if steps[worst] > limit:
                out[f'{role} ({kind})'] = (float(steps[worst]),
                                           (int(ordered[worst]) - origin) * 1e-9)
    return out


def missed_deadlines(run: RunData) -> tuple[int, int]:
    """
    Return how many simulator steps applied an answer older than the step before.

    The ground truth's ``command_time`` is the stamp of the answer the plant applied
    over the step that ends at ``time`` (-1: none yet); in realtime mode a late answer
    leaves the plant holding the previous one (a missed deadline).

    :param run: the run.
    :return: ``(missed steps, steps with an applied answer)``; ``(0, 0)`` without
        ground truth.
    """
    time, applied = run.truth.values.get('time'), run.truth.values.get('command_time')
    if time is None or applied is None or time.size < 2:
        return 0, 0
    steps = np.unique(time)
    if steps.size < 2:
        return 0, 0
    period = float(np.median(np.diff(steps)))
    known = applied >= 0.0
    late = known & (time - applied > 1.5 * period)
    return int(np.unique(time[late]).size), int(np.unique(time[known]).size)


def conflicting_stamps(run: RunData) -> dict[str, int]:
    """
    Return, per topic role, how many stamps were recorded twice with different values.

    A re-sent message repeats its values; different values under one stamp mean two
    sources (e.g. another run on the same ROS domain), whose steps the series mixes.

    :param run: the run.
    :return: role -> number of conflicting stamps, only roles with some.
    """
    out = {}
    for role, samples in (*run.inputs.items(), ('steering', run.steering),
                          ('ground_truth', run.truth)):
        if len(samples) < 2 or not samples.values:
            continue
        order = np.lexsort((samples.order, samples.stamp_ns))
        stamps = samples.stamp_ns[order]
        same = stamps[1:] == stamps[:-1]
        if not same.any():
            continue
        differ = np.zeros(same.shape, dtype=bool)
        # the simulator re-sends a step with the command it then knows: compare its state
        names = (STATE_FIELDS if role == 'ground_truth' else samples.values)
        for name in names:
            v = samples.values.get(name, np.full(len(samples), np.nan))[order]
            if v.dtype == object:       # the curvature preview's points: tuples
                differ |= np.array([a != b for a, b in zip(v[1:], v[:-1])], dtype=bool)
                continue
            differ |= ~((v[1:] == v[:-1]) | (np.isnan(v[1:]) & np.isnan(v[:-1])))
        count = np.unique(stamps[1:][same & differ]).size
        if count:
            out[role] = int(count)
    return out


def run_labels(run: RunData) -> dict[str, Any]:
    """
    Return what tells runs apart: bag, scenario, plant, mode, rate, law, schedule.

    :param run: the run.
    :return: ``bag, scenario, plant, mode, rate_hz, law, schedule`` ('n/a' where the bag
        does not say; ``law`` is ``paper`` for a bag from before the parameter existed,
        ``a -> b`` for a run whose law was set while it ran, as its debug topic says).
    """
    scenario = 'n/a'
    text = scenario_text(run)     # the run's own simulator's (a bag of several vehicles)
    if text:
        try:
            loaded = yaml.safe_load(text) or {}
            scenario = str((loaded.get('scenario') or {}).get('name', 'n/a'))
        except (yaml.YAMLError, AttributeError):
            scenario = 'n/a'
    plant, ctl = run.plant_params, run.controller_params
    rate = plant.get('rate_hz', ctl.get('rate_hz'))
    law = str(ctl.get('law', 'paper' if ctl else 'n/a'))
    # a law set at run time: the debug topic names the law of every answer
    # (``law:<name>``); before, only the start-up law was named
    named = {key[4:]: values for key, values in run.debug.values.items()
             if key.startswith('law:') and key[4:] in LAW_NAMES}
    if len(named) > 1:
        order = np.argsort(run.debug.stamp_ns, kind='stable')
        sequence: list[str] = []
        for i in order:
            here = [name for name, values in named.items() if math.isfinite(values[i])]
            if len(here) == 1 and (not sequence or sequence[-1] != here[0]):
                sequence.append(here[0])
        if len(sequence) > 1:
            law = ' -> '.join(sequence)
    return {
        'bag': run.bag.name,
        'scenario': scenario,
        'plant': str(plant.get('plant.model', 'n/a')),
        'mode': str(plant.get('mode', 'n/a')),
        'rate_hz': float(rate) if rate is not None else math.nan,
        'law': law,
        'schedule': str(ctl.get('controller.schedule', 'n/a')),
    }


def run_label(row: Mapping[str, Any]) -> str:
    """
    Return a legend label naming a row's bag, scenario, plant, mode, rate and law.

    :param row: a row of :func:`bag_row`.
    :return: e.g. ``fixed_37 (paper_r400, linear, lockstep 100 Hz, fixed)``.
    """
    rate = f' {row["rate_hz"]:g} Hz' if math.isfinite(row['rate_hz']) else ''
    return (f'{row["bag"]} ({row["scenario"]}, {row["plant"]}, {row["mode"]}{rate}, '
            f'{law_label(row)})')


def law_label(row: Mapping[str, Any]) -> str:
    """
    Return the steering law of a row: the d_v schedule for the paper's law, else the law.

    :param row: a row of :func:`bag_row`.
    :return: e.g. ``fixed``, ``paper`` (eq. 26) or ``cg_compensated``.
    """
    law = row.get('law', 'paper')
    return str(row['schedule']) if law in ('paper', 'n/a') else str(law)


#: the ground truth's channels the metrics read (the wheel angle has no stand-in)
TRUTH_CHANNELS = ('y_cg', 'eps_r', 'rho', 'steering')


def truth_not_finite(run: RunData) -> str:
    """
    Return the note on ground-truth values that are not finite ('' if none).

    :func:`run_series` takes the measurements in their place (the wheel angle: missing),
    as where the ground truth is not recorded.

    :param run: the run.
    :return: e.g. ``ground truth: 10 eps_r values not finite (NaN or inf): the
        measurements stand in there``.
    """
    counts = {name: int(np.count_nonzero(~np.isfinite(run.truth.values[name])))
              for name in TRUTH_CHANNELS if name in run.truth.values}
    bad = {name: count for name, count in counts.items() if count}
    if not bad:
        return ''
    listed = ', '.join(f'{count} {name}' for name, count in bad.items())
    return (f'ground truth: {listed} value(s) not finite (NaN or inf): the measurements '
            'stand in there' + (' (the wheel angle: missing)' if 'steering' in bad else ''))


def _assumptions(run: RunData) -> list[str]:
    """Return what the analysis assumes because the bag does not record it."""
    params = run.controller_params
    if not params:
        return [f'assumed: the bag has no {run.controller_node} parameters; the default '
                f'vehicle (d_s = {VehicleParams().d_s:g} m) and controller (schedule '
                f'{ControllerParams().schedule}) are used for d_s and any law re-run']
    missing = [name for name in ('vehicle.d_s', 'controller.schedule')
               if name not in params]
    return ([f'assumed: defaults for {", ".join(missing)} (not in the bag)']
            if missing else [])


#: a stretch whose memory ended learned at least this much (``memory_weight``: the
#: memory is then within a tenth of the way from its seed to what the curves taught) is
#: taken over an earlier one. Half (the curves weighing as much as the seed) was
#: reached 0.2 s into a 3.4 m/s^2 curve, halfway from the seed (dev-probe50)
MEMORY_LEARNED = 0.9


def final_compliance_memory(run: RunData) -> tuple[float, str]:
    """
    Return the default law's compliance memory at the end of a run, to seed the next.

    The memory (``~/debug`` ``compliance_memory``, over the model's ``eta``) at the law's
    last answer. It starts again from its seed where its ``~/debug``
    ``memory_generation`` changes (a restart of the law: a time jump, stale inputs, a bad
    input; a new law after a switch away and back; a retune that restarted the
    estimate), where another law answered between two of its answers, and, in bags
    without ``memory_generation``, where it is back exactly at its first value. Of the
    stretches between, the last whose memory ended learned at least
    :data:`MEMORY_LEARNED` (``~/debug`` ``memory_weight``) gives the value, else the one
    that ended learned most (a restart late in a curve leaves a stretch that learned for
    a fraction of a second); the note says so where that is not the run's end. Without
    ``memory_weight`` (older bags), the last stretch that moved the memory by more than
    0.5 %.

    :param run: the run.
    :return: the value (NaN where the law kept no memory: another law, no debug topic)
        and a note ('' if none).
    """
    values = run.debug.values.get('compliance_memory')
    if values is None or values.dtype == object or not values.size:
        return math.nan, ''
    ordered = np.lexsort((run.debug.order, run.debug.stamp_ns))
    memory, stamps = values[ordered], run.debug.stamp_ns[ordered]
    kept = np.flatnonzero(np.isfinite(memory))
    if not kept.size:
        return math.nan, ''

    def field(name: str) -> Optional[Array]:
        column = run.debug.values.get(name)
        return None if column is None or column.dtype == object else column[ordered][kept]
    # a new start: another law answered between two of its answers ...
    starts = np.diff(kept) > 1
    memory, stamps = memory[kept], stamps[kept]
    number = field('memory_generation')
    if number is not None:
        # ... or its number changed
        starts |= (number[1:] != number[:-1]) & np.isfinite(number[1:])
    else:
        # (a bag from before the number, whose seed was the model: back at it exactly)
        starts |= (memory[1:] == memory[0]) & (memory[:-1] != memory[0])
    begins = [0, *(np.flatnonzero(starts) + 1).tolist()]
    if len(begins) == 1:
        return float(memory[-1]), ''
    ends = [*begins[1:], memory.size]
    weight = field('memory_weight')
    if weight is not None:
        learned = [float(weight[b - 1]) if np.isfinite(weight[b - 1]) else 0.0 for b in ends]
        enough = [k for k, w in enumerate(learned) if w >= MEMORY_LEARNED]
        best = enough[-1] if enough else max(range(len(learned)),
                                             key=lambda k: (learned[k], k))
        how = (f'learned most ({learned[best]:.2f} of it learned, {learned[-1]:.2f} after '
               'the last start)')
    else:
        moved = [k for k, (a, b) in enumerate(zip(begins, ends))
                 if np.max(np.abs(memory[a:b] - memory[a])) > 5e-3 * abs(memory[a])]
        best = moved[-1] if moved else len(begins) - 1
        how = 'moved it by more than 0.5 %, the last to'

    def at(index: int) -> str:
        return f'{(int(stamps[index]) - int(stamps[0])) * 1e-9:.3g} s after its first answer'
    if best == len(begins) - 1:
        return float(memory[-1]), (
            f'compliance_memory_final_ratio: the memory started again (a restart, a switch '
            f'of law or a retune) {at(begins[-1])} and learned enough after it')
    return float(memory[ends[best] - 1]), (
        f'compliance_memory_final_ratio: the memory started again (a restart, a switch of '
        f'law or a retune) {at(begins[-1])}; the value is its memory {at(ends[best] - 1)}, '
        f'at the end of the stretch that {how}')


def _scenario_span(run: RunData) -> Optional[tuple[Array, float, float]]:
    """Return the ground truth's step times, the scenario's duration and the step [s]."""
    time = run.truth.values.get('time')
    text = scenario_text(run)
    if time is None or text is None:
        return None
    steps = np.unique(time[np.isfinite(time)])
    try:
        duration = float((yaml.safe_load(text) or {})['scenario']['duration'])
    except (yaml.YAMLError, KeyError, TypeError, ValueError):
        return None
    if steps.size < 2 or not math.isfinite(duration):
        return None
    return steps, duration, float(np.median(np.diff(steps)))


def finished_at(run: RunData) -> Optional[int]:
    """
    Return when a simulator's run that finished its scenario received its last input.

    What the controller tells after that is the simulation's end (its clock stops, its
    inputs stop), not a fault of the run. A run stopped early, a real vehicle's (no
    scenario), or one whose inputs died mid-run has no such end: what the controller
    tells after its last input is a fault (dev-probe111: a vehicle whose sensors died
    read OK, its ERROR 'stale inputs' called the run's end).

    :param run: the run.
    :return: the last input's receive time (the recorder's clock) [ns], or None.
    """
    span = _scenario_span(run)
    if span is None or span[0][-1] < span[1] - 1.5 * span[2]:
        return None
    received = [int(samples.recv_ns.max()) for samples in run.inputs.values() if len(samples)]
    return max(received) if received else None


def run_span(run: RunData) -> list[str]:
    """
    Return what the bag misses of its simulator's scenario: a late start, an early end.

    The ground truth's ``time`` is the simulator's clock from the scenario's start; a
    complete run's steps reach its ``duration`` to a step. A run stopped or killed
    before (SIGINT to ``closed_loop``), or a recorder started after the run began, read
    like a complete run before (dev-probe93).

    :param run: the run.
    :return: the notes (none without ground truth or a scenario with a duration).
    """
    span = _scenario_span(run)
    if span is None:
        return []
    steps, duration, period = span
    notes = []
    if steps[0] > 1.5 * period:
        notes.append(f'late start: the bag begins at t = {steps[0]:.3g} s of the run (a '
                     'recorder started after it); the metrics cover only what it holds')
    if steps[-1] < duration - 1.5 * period:
        notes.append(f'stopped early: the run ends at t = {steps[-1]:.3g} s of the '
                     f"scenario's {duration:g} s (stopped or killed before its end); the "
                     'metrics cover only that')
    return notes


def bag_row(run: RunData, series: RunSeries,
            label: Optional[str] = None) -> dict[str, Any]:
    """
    Return the metrics table row of one recorded run.

    :param run: the run.
    :param series: its series.
    :param label: the row's ``run`` label (default: the bag's name).
    :return: labels (:func:`run_labels`), errors at the CG, look-down and look-ahead
        point, relative-yaw step response, steering command and wheel angle, latency
        p50/p99, counts, the largest input gap, ``compliance_memory_final_ratio`` (the
        default law's memory of the rear compliance over the model's at its end, the
        ``lane_keeping.compliance_memory_seed`` of the car's next run:
        :func:`final_compliance_memory`; NaN for other laws), ``diagnostics``: the worst
        level the controller's ``/diagnostics`` reached (``-``: none recorded), and
        ``notes``: assumptions, why a metric is empty, and the reasons of its statuses at
        WARN and up.
    """
    params = run.controller_params
    d_s = float(params.get('vehicle.d_s', VehicleParams().d_s))
    row: dict[str, Any] = {'run': label or run.bag.name, **run_labels(run),
                           'speed_mps': round(float(series.channels['v_x'][0]), 3)}
    metrics = run_metrics(series.time, series.channels, d_s)
    notes = _assumptions(run)
    broken = truth_not_finite(run)
    if broken:
        notes.append(broken)
    measured = metrics.pop('notes')
    if measured:
        notes.append(measured)
    row.update(metrics)
    lat = series.latency
    row['latency_p50_ms'] = row['latency_p99_ms'] = math.nan
    early = int((lat < 0.0).sum())
    if lat.size < MIN_LATENCY_SAMPLES:
        notes.append(f'latency: {lat.size} answered steps, too few (needs '
                     f'{MIN_LATENCY_SAMPLES})')
    elif np.percentile(lat, 50) <= 0.0:
        notes.append(f'latency: {early} of {lat.size} answers were recorded before '
                     "their lateral error (the recorder's receive order, e.g. a recovered "
                     'or overloaded recording): its receive times do not measure latency')
    else:
        row['latency_p50_ms'] = float(np.percentile(lat, 50) * 1e3)
        if lat.size >= MIN_P99_SAMPLES:
            row['latency_p99_ms'] = float(np.percentile(lat, 99) * 1e3)
        else:
            notes.append(f'latency_p99: {lat.size} answered steps, too few (needs '
                         f'{MIN_P99_SAMPLES})')
        if early:
            notes.append(f'latency: {early} of {lat.size} answers were recorded before '
                         'their lateral error (the recorder receives them in its own '
                         'order): latency is as the recorder saw it')
    row['compliance_memory_final_ratio'], said = final_compliance_memory(run)
    if said:
        notes.append(said)
    angles = run.steering.values.get('angle', np.zeros(0))
    bad = int((~np.isfinite(angles)).sum())
    if bad:
        # a controller sent NaN: before, the metrics stepped over them unsaid
        # (dev-probe93: a bag with 10 NaN commands gave the clean bag's row)
        notes.append(f'steering: {bad} of {angles.size} recorded commands are not finite '
                     '(NaN or inf): the steering metrics skip a NaN, an inf is their '
                     'peak')
    row['steps'] = int(series.time.size)
    row['unanswered'] = series.unanswered
    drops = recorder_drops(run)
    row['dropped'] = -1 if drops is None else drops
    if drops is None:
        notes.append('dropped: the recorder did not count lost messages (-1)')
    conflicts = conflicting_stamps(run)
    if conflicts:
        notes.append('conflicting: ' + ', '.join(
            f'{role} {count} stamps recorded twice with different values'
            for role, count in conflicts.items()) + ' (two sources, e.g. another run on '
            'the same ROS domain: the metrics mix them)')
    if run.bag is not None and run.bag.is_dir() and any(run.bag.glob('*.mcap.truncated')):
        notes.append(f'recovered: the recorder was killed and the bag recovered; it ends '
                     f'{float(series.time[-1]):.3g} s after its first step, and the '
                     'metrics cover only that')
    else:
        notes += run_span(run)
    missed, applied = missed_deadlines(run)
    if missed:
        notes.append(f'missed deadlines: {missed} of {applied} simulator steps applied an '
                     'older answer (the plant held its previous command; unanswered '
                     'counts only answers missing from the bag)')
    gaps = input_gaps(run, arrival=run.plant_params.get('mode') != 'lockstep')
    row['max_gap_s'] = max((g for g, _ in gaps.values()), default=0.0)
    if gaps:
        # a gap of another input before the first lateral error starts at a negative t:
        # said so (dev-probe93: 't = -0.5 s' unexplained)
        notes.append('gaps: ' + ', '.join(
            f'{role} {gap:.3g} s at t = {start:.3g} s'
            + (' (before the first lateral error)' if start < 0.0 else '')
            for role, (gap, start) in gaps.items()))
    summary = run_diagnostics(run)
    row['diagnostics'] = summary.worst if summary is not None else '-'
    # dev-sc49: what the controller warned of during the run (a lateral error in cm, a
    # frozen yaw rate ...) was in the bag and in no report
    warned = summary_note(summary) if summary is not None else ''
    if warned:
        notes.append(warned)
    if run.diagnostics is not None:
        notes += [f'diagnostics: {said}' for said in run.diagnostics.notes()]
    row['notes'] = '; '.join(notes)
    return row


def run_diagnostics(run: RunData) -> Optional[DiagnosticsSummary]:
    """
    Return what the run's controller told on ``/diagnostics``, summed up.

    :param run: the run.
    :return: the summary (times from the first lateral-error stamp; a simulator's run
        that finished its scenario ends where its last input was received:
        :func:`finished_at`); None: the bag has no ``/diagnostics``.
    """
    if run.diagnostics is None or run.diagnostics.wrong_type:
        return None
    lateral = run.inputs.get('lateral_error', Samples.empty())
    return summarize(run.diagnostics.reports,
                     int(lateral.stamp_ns.min()) if len(lateral) else 0, finished_at(run))


def speed_points(series_list: list[RunSeries]) -> tuple[Array, Array]:
    """Return the ``(v_x, d_v)`` of every step of all runs, for the d_v-vs-speed plot."""
    if not series_list:
        return np.zeros(0), np.zeros(0)
    return (np.concatenate([s.channels['v_x'] for s in series_list]),
            np.concatenate([s.channels['d_v'] for s in series_list]))
