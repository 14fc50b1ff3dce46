"""The compiled loop's arguments: the one owner of their grouping, packing and unpacking.

One call of the loop (:func:`~gfb_env.integrator.stages._advance`) takes named groups: the
integrator's arrays ``y`` and ``clock`` (:class:`~gfb_env.integrator.StepperState`), the ``schedule``,
the model's kernel arguments, :class:`Jacobian`, :class:`Factorization`, :class:`LoopOptions`,
:class:`Recording`, the counter and extreme vectors, and :class:`Forcing` (or None).  numba passes
NamedTuples by value; the arrays in them are shared.

A batch (:mod:`gfb_env.integrator.batch`) stacks the groups of many calls: every array group gains a
leading env axis (:class:`BatchArrays`), and every scalar of a call (its clock, schedule, options,
recording window, forcing and status) is one row of the structured array :data:`CALL_DTYPE`, whose
fields are named after the groups' fields.  :func:`call_row` packs one prepared call
into a row (Python) and :func:`unpack_row` rebuilds the loop's scalar groups from it (compiled), so the
single call and each env of a batch pass the same groups of the same types to the same compiled loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "BatchArrays",
    "CALL_DTYPE",
    "CLOCK_FIELDS",
    "Factorization",
    "Forcing",
    "Jacobian",
    "LoopOptions",
    "Recording",
    "SCHEDULE_FIELDS",
    "call_row",
    "store_clock",
    "unpack_row",
]


class Jacobian(NamedTuple):
    """The blocks of J (see :mod:`gfb_env._kernels`), refreshed in place."""

    Ad: np.ndarray
    Ap: np.ndarray
    Am: np.ndarray
    Er: np.ndarray
    Rr: np.ndarray
    Srr: np.ndarray


class Factorization(NamedTuple):
    """Workspace of the factors of ``I - h/2 J`` and the solver's static parameters."""

    Dlu: np.ndarray
    Dpiv: np.ndarray
    Uhat: np.ndarray
    Y: np.ndarray
    Slu: np.ndarray
    Spiv: np.ndarray
    n_rows: int
    sparse: bool
    size_tag: tuple


class LoopOptions(NamedTuple):
    """The loop's view of :class:`~gfb_env.integrator.IntegratorOptions` (its step-size controller
    flattened in) and the call's ``max_steps``."""

    rtol: float
    atol: float
    min_step: float
    max_step: float
    touchdown_film_thickness: float
    max_newton_iterations: int
    newton_tol: float
    factorization_ratio: float
    slow_newton_iterations: int
    safety: float
    reject_safety: float
    min_factor: float
    max_factor: float
    error_exponent: float
    newton_failure_factor: float
    max_steps: int

    @staticmethod
    def head_of(options) -> tuple:
        """Every field but ``max_steps`` from an IntegratorOptions (a call appends its max_steps)."""
        o, c = options, options.controller
        return (
            o.rtol, o.atol, o.min_step, o.max_step, o.touchdown_film_thickness, o.max_newton_iterations,
            o.newton_tol, o.factorization_ratio, o.slow_newton_iterations, c.safety, c.reject_safety,
            c.min_factor, c.max_factor, c.error_exponent, c.newton_failure_factor,
        )  # fmt: skip


class Recording(NamedTuple):
    """Dense output: rows ``[tau, s[indices]..., min H]`` every ``interval`` from ``first_tau``."""

    indices: np.ndarray
    interval: float
    first_tau: float
    buffer: np.ndarray


class Forcing(NamedTuple):
    """The external forcing of one call (:mod:`gfb_env.forcing`); an unforced call passes None instead."""

    unbalance: float  # U
    angle: float  # theta at the call's start plus the unbalance phase
    shocks: np.ndarray  # rows HalfSineShock.as_row(), shape (k, 4)
    max_step: float  # the step limit that resolves the unbalance forcing (inf without one)


#: The loop's clock, as :attr:`StepperState.clock` orders it.
CLOCK_FIELDS = ("tau", "step", "previous_step", "previous_step2", "history")
#: The call's schedule: the end time and Lambda, D_W at both ends of the call.
SCHEDULE_FIELDS = ("tau_end", "bearing_number_start", "bearing_number_end", "foil_damping_start")
SCHEDULE_FIELDS += ("foil_damping_end",)
_RECORDING_FIELDS = ("record_interval", "record_first_tau", "record_row_start", "record_row_end")
_FORCING_FIELDS = ("forced", "unbalance", "forcing_angle", "forcing_max_step", "n_shocks")
_INT_FIELDS = {"history", "max_newton_iterations", "slow_newton_iterations", "max_steps", "n_shocks"}
_INT_FIELDS |= {"record_row_start", "record_row_end", "status"}
_NAMES = CLOCK_FIELDS + SCHEDULE_FIELDS + LoopOptions._fields + _RECORDING_FIELDS + _FORCING_FIELDS
_NAMES += ("status",)
#: One row per env of a batch: every scalar of its call.  In: the clock, schedule, options, the rows
#: ``[record_row_start, record_row_end)`` of its sample buffer, the forcing (``forced``: whether a
#: Forcing is passed, with ``n_shocks`` rows of its shock array); out: the clock and the status code.
CALL_DTYPE = np.dtype(
    [(k, np.bool_ if k == "forced" else np.int64 if k in _INT_FIELDS else np.float64) for k in _NAMES]
)


def call_row(clock: tuple, schedule: tuple, options: LoopOptions, recording: Recording, rows: tuple,
             forcing: Forcing | None) -> tuple:  # fmt: skip
    """A call's scalars as a :data:`CALL_DTYPE` row (in its field order: the groups' in turn)."""
    if forcing is None:
        force = (False, 0.0, 0.0, 0.0, 0)
    else:
        force = (True, forcing.unbalance, forcing.angle, forcing.max_step, len(forcing.shocks))
    return (*clock, *schedule, *options, recording.interval, recording.first_tau, *rows, *force, 0)


@njit(inline="always")
def unpack_row(c):
    """The loop's scalar groups of a :data:`CALL_DTYPE` row ``c``, field by field by name: ``(clock,
    schedule, options, (record_interval, record_first_tau), (row_start, row_end))``."""
    clock = (c.tau, c.step, c.previous_step, c.previous_step2, c.history)
    schedule = (
        c.tau_end, c.bearing_number_start, c.bearing_number_end, c.foil_damping_start, c.foil_damping_end
    )  # fmt: skip
    opt = LoopOptions(
        rtol=c.rtol, atol=c.atol, min_step=c.min_step, max_step=c.max_step,
        touchdown_film_thickness=c.touchdown_film_thickness, max_newton_iterations=c.max_newton_iterations,
        newton_tol=c.newton_tol, factorization_ratio=c.factorization_ratio,
        slow_newton_iterations=c.slow_newton_iterations, safety=c.safety, reject_safety=c.reject_safety,
        min_factor=c.min_factor, max_factor=c.max_factor, error_exponent=c.error_exponent,
        newton_failure_factor=c.newton_failure_factor, max_steps=c.max_steps,
    )  # fmt: skip
    window = (c.record_row_start, c.record_row_end)
    return clock, schedule, opt, (c.record_interval, c.record_first_tau), window


@njit(inline="always")
def store_clock(c, clock) -> None:
    """Write the loop's clock at the end back into the row ``c``."""
    c.tau = clock[0]
    c.step = clock[1]
    c.previous_step = clock[2]
    c.previous_step2 = clock[3]
    c.history = clock[4]


class BatchArrays(NamedTuple):
    """The array arguments of a batch, stacked along a leading env axis (but ``record_indices``, which
    the batch shares).  A parallel loop cannot take a tuple: the parallel kernel unpacks this by name
    before its ``prange`` and repacks it by keyword inside (numba refuses any name it lacks)."""

    calls: np.ndarray  # (N,) of CALL_DTYPE
    y: np.ndarray  # (N, 5, n): StepperState.arrays per env
    ip: np.ndarray  # the model's kernel_args, stacked
    fp: np.ndarray
    sn: np.ndarray
    cs: np.ndarray
    Ad: np.ndarray  # Jacobian, stacked
    Ap: np.ndarray
    Am: np.ndarray
    Er: np.ndarray
    Rr: np.ndarray
    Srr: np.ndarray
    Dlu: np.ndarray  # Factorization's arrays, stacked
    Dpiv: np.ndarray
    Uhat: np.ndarray
    Yw: np.ndarray
    Slu: np.ndarray
    Spiv: np.ndarray
    record_indices: np.ndarray  # Recording.indices (shared)
    record_buffers: np.ndarray  # (N, rows, k): each env's Recording.buffer is rows of it
    stats: np.ndarray  # (N, 9) counters
    ext: np.ndarray  # (N, 9) extremes
    shocks: np.ndarray  # (N, kmax, 4): Forcing.shocks, n_shocks rows of each
