"""The trapezoidal stepper: :class:`TrapezoidalIntegrator` (see :mod:`gfb_env.integrator` for the
method).  One :meth:`~TrapezoidalIntegrator.advance` is three parts: :meth:`~TrapezoidalIntegrator.prepare`
(Python: checks and the compiled call's argument groups), the compiled loop
(:func:`gfb_env.integrator.stages._advance`) and :meth:`~TrapezoidalIntegrator._finish` (Python: the new
:class:`~gfb_env.integrator.StepperState` and the result)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import numpy as np

from gfb_env import _kernels as K
from gfb_env import forcing as F
from gfb_env.forcing import HalfSineShock, Unbalance
from gfb_env.integrator.arguments import Factorization, Forcing, Jacobian, LoopOptions, Recording
from gfb_env.integrator.controller import WHIRL_FREQUENCY_RATIO
from gfb_env.integrator.options import IntegratorOptions
from gfb_env.integrator.results import (
    _EPSMAX,
    _ETAMAX,
    _ETAMIN,
    _EVETA,
    _EVT,
    _EVXI,
    _EXTREMES_START,
    _FAILED,
    _MAX_STEPS,
    _MINH,
    _NREC,
    _STATUS_OF_CODE,
    _TOUCHDOWN,
    _XIMAX,
    _XIMIN,
    AdvanceResult,
    IntegrationError,
    IntegratorStatistics,
    TouchdownEvent,
    Trajectory,
)
from gfb_env.integrator.stages import _advance
from gfb_env.integrator.state import StepperState
from gfb_env.model import GFBModel

__all__ = ["DEFAULT_MAX_STEPS", "PreparedCall", "TrapezoidalIntegrator"]

_DEFAULT_OPTIONS = IntegratorOptions()
_NO_SHOCKS = np.zeros((0, 4))
#: The default ``max_steps`` of one :meth:`TrapezoidalIntegrator.advance`.
DEFAULT_MAX_STEPS = 10_000_000
_NO_INDICES = np.zeros(0, dtype=np.int64)


class PreparedCall(NamedTuple):
    """One prepared call of the compiled loop (:meth:`TrapezoidalIntegrator.prepare`): its arguments
    and what :meth:`TrapezoidalIntegrator._finish` needs besides the loop's outputs."""

    st: StepperState  # the state the call starts from (its arrays are advanced in place)
    schedule: tuple  # (tau_end, Lambda_0, Lambda_1, D_W0, D_W1)
    span: float
    rate: float  # theta'' of the call's ramp
    options: LoopOptions
    recording: Recording
    rec_buf: np.ndarray  # the whole sample buffer (a sample at the start in row 0 when first == 1)
    first: int
    stats: np.ndarray
    ext: np.ndarray
    forcing: Forcing | None
    max_steps: Any  # as passed (it appears in the max_steps message)


# ------------------------------------------------------------------------------------------------
def _check_unbalance(unbalance: Unbalance | None) -> None:
    if unbalance is not None and not isinstance(unbalance, Unbalance):
        raise ValueError(f"unbalance must be an Unbalance or None, got {type(unbalance).__name__}")


class TrapezoidalIntegrator:
    """Adaptive trapezoidal-rule stepper for a :class:`~gfb_env.model.GFBModel` (see module docstring).

    Args:
        model: the coupled model.
        state: initial state (copied).
        bearing_number: Lambda at the initial time.
        foil_damping: D_W at the initial time (viscoelastic foil only).
        tau: initial nondimensional time.
        options: every setting (:class:`~gfb_env.integrator.IntegratorOptions`: tolerances, step
            limits, touchdown threshold, Newton, the step-size controller); default the defaults.
        **overrides: fields of :class:`~gfb_env.integrator.IntegratorOptions` that replace those of
            ``options`` (e.g. ``rtol=1e-5``), validated by it; read them back as ``it.options.rtol``.
        unbalance: the rotor's :class:`~gfb_env.forcing.Unbalance` (None: none; see
            :meth:`set_unbalance`); its forcing uses the rotation angle theta, carried exactly from
            ``rotation_angle`` (theta' = Lambda; :attr:`rotation_angle`).

    Base shocks (:meth:`add_shock`): steps land on the start and end of each pulse and take at most 1/32
    of it inside (the trapezoidal quadrature of a half sine in n steps loses ``pi^2 / (12 n^2)`` of its
    impulse: 1.3 % at n = 8, 0.08 % at 32); with an unbalance the step is at most ``2 pi / (N Lambda)``
    (``options.steps_per_revolution``).
    """

    def __init__(
        self,
        model: GFBModel,
        state: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        tau: float = 0.0,
        *,
        options: IntegratorOptions | None = None,
        unbalance: Unbalance | None = None,
        rotation_angle: float = 0.0,
        **overrides: Any,
    ):
        if options is None:
            options = _DEFAULT_OPTIONS
        elif not isinstance(options, IntegratorOptions):
            raise ValueError(f"options must be an IntegratorOptions or None, got {type(options).__name__}")
        self.model = model
        self.options = options.replace(**overrides)  # the one owner of the settings and their checks
        self._kernel_args = model.kernel_args()
        self._shape_key = _shape_key(model)  # BatchAdvance batches integrators of one shape
        self._record_key: tuple | None = None  # the last record_indices (see _record_indices)
        self._record_idx = _NO_INDICES
        self._jacobian = Jacobian(**model.new_blocks())
        nc, m = model.grid.n_columns, model.layout.block_size
        nb = m + 4
        self._factorization = Factorization(
            Dlu=np.zeros((nc, m, m)),
            Dpiv=np.zeros((nc, m), dtype=np.int64),
            Uhat=np.zeros((nc, m, m)),
            Y=np.zeros((nc, m, nb)),
            Slu=np.zeros((nb, nb)),
            Spiv=np.zeros(nb, dtype=np.int64),
            n_rows=model.grid.n_rows,
            sparse=model.sparse_offdiagonal_blocks,
            size_tag=K.size_tag(m),
        )
        self.reset(
            state, bearing_number, foil_damping, tau, rotation_angle=rotation_angle, unbalance=unbalance
        )

    # ------------------------------------------------------------------------------------------
    def reset(
        self,
        state: np.ndarray,
        bearing_number: float,
        foil_damping: float = 1.0,
        tau: float = 0.0,
        rotation_angle: float = 0.0,
        unbalance: Unbalance | None | str = "keep",
    ) -> None:
        """Restart from ``state`` at time ``tau`` with the rotation angle theta = ``rotation_angle``
        (forgets the step history and pending shocks; keeps the unbalance unless one is given)."""
        self.model.check_operating_point(bearing_number, foil_damping)
        s = np.array(self.model.layout.check(state), dtype=float, copy=True)
        if not np.all(np.isfinite(s)):
            raise ValueError("state must be finite")
        if not math.isfinite(rotation_angle):
            raise ValueError(f"rotation_angle must be finite, got {rotation_angle!r}")
        if isinstance(unbalance, str):
            unbalance = getattr(self, "_stepper", None) and self._stepper.unbalance
        _check_unbalance(unbalance)
        self._stepper = StepperState.start(
            self.model, s, bearing_number, foil_damping, tau, self.options.first_step,
            rotation_angle=math.fmod(float(rotation_angle), 2.0 * math.pi) % (2.0 * math.pi),
            unbalance=unbalance if unbalance is not None and unbalance.magnitude != 0.0 else None,
        )  # fmt: skip

    @property
    def options(self) -> IntegratorOptions:
        """The settings (frozen; assign a new :class:`~gfb_env.integrator.IntegratorOptions` to change
        them between calls)."""
        return self._options

    @options.setter
    def options(self, options: IntegratorOptions) -> None:
        if not isinstance(options, IntegratorOptions):
            raise ValueError(f"options must be an IntegratorOptions, got {type(options).__name__}")
        self._options = options
        self._loop_options = LoopOptions.head_of(options)  # every call appends its max_steps
        self._last_loop_options: tuple | None = None  # (head, max_steps, LoopOptions) of the last call
        # the step limit at a settled operating point (opt-in, controller.WhirlGrowthControl)
        self._growth = options.whirl_growth_control
        if self._growth is not None:
            head = list(self._loop_options)
            head[LoopOptions._fields.index("max_step")] = self._growth.settled_max_step
            self._settled_loop_options = tuple(head)

    @property
    def rotation_angle(self) -> float:
        """theta at :attr:`tau` in [0, 2 pi): the rotor's angle from the downward vertical toward
        +xi (theta' = Lambda, carried exactly; see :mod:`gfb_env.forcing`)."""
        return self._stepper.rotation_angle

    @property
    def unbalance(self) -> Unbalance | None:
        return self._stepper.unbalance

    @property
    def shocks(self) -> tuple[HalfSineShock, ...]:
        """The base shocks scheduled and not yet over."""
        return self._stepper.shocks

    def set_unbalance(self, unbalance: Unbalance | None) -> None:
        """Switch the unbalance (None: none) from now on.  The forcing jumps: k at the current state is
        re-evaluated with it (the step history is kept, as for a jump of the damping command)."""
        _check_unbalance(unbalance)
        st = self._stepper
        old = st.unbalance
        new = unbalance if (unbalance is not None and unbalance.magnitude != 0.0) else None
        if new == old:
            return
        f = st.f.copy()
        L = self.model.layout
        for ub, sign in ((old, -1.0), (new, 1.0)):
            if ub is not None:
                a = F.unbalance_acceleration(
                    ub.magnitude,
                    st.rotation_angle + ub.phase_rad,
                    st.bearing_number,
                    st.rotation_acceleration,
                )
                f[L.xi_dot_index] += sign * a[0]
                f[L.eta_dot_index] += sign * a[1]
        if new is None:
            # bit for bit the unforced k again (no rounding residue of adding and removing)
            f = self.model.rhs(st.s, st.bearing_number, st.foil_damping)
        self._stepper = dataclasses.replace(st, f=f, unbalance=new)

    def add_shock(self, shock: HalfSineShock) -> None:
        """Schedule a base shock (it must not start before :attr:`tau`: its acceleration starts at zero,
        so k at the current state stays valid).  Steps land on its start and end."""
        if not isinstance(shock, HalfSineShock):
            raise ValueError(f"shock must be a HalfSineShock, got {type(shock).__name__}")
        st = self._stepper
        if shock.start_tau < st.tau:
            raise ValueError(f"shock start_tau {shock.start_tau:g} is before the current time {st.tau:g}")
        shocks = tuple(sorted(st.shocks + (shock,), key=lambda q: (q.start_tau, q.duration_tau)))
        self._stepper = dataclasses.replace(st, shocks=shocks)

    @property
    def tau(self) -> float:
        return self._stepper.tau

    @property
    def state(self) -> np.ndarray:
        """Current state (a copy)."""
        return self._stepper.s.copy()

    @property
    def bearing_number(self) -> float:
        return self._stepper.bearing_number

    @property
    def foil_damping(self) -> float:
        return self._stepper.foil_damping

    @property
    def step_size(self) -> float:
        """The step size the next step will try."""
        return self._stepper.step

    @property
    def statistics(self) -> IntegratorStatistics:
        """Work counters since the last :meth:`reset`."""
        return self._stepper.statistics

    def snapshot(self) -> StepperState:
        """Everything the continuation depends on (a copy; restore with :meth:`restore`)."""
        return self._stepper.copy()

    def restore(self, snapshot: StepperState) -> None:
        """Continue from ``snapshot`` (copied): the continuation is bit for bit the original one."""
        if snapshot.s.shape != (self.model.layout.size,):
            raise ValueError(
                f"snapshot state has shape {snapshot.s.shape}, the model needs ({self.model.layout.size},)"
            )
        self._stepper = snapshot.copy()

    # ------------------------------------------------------------------------------------------
    def _forcing_of_call(
        self, st: StepperState, span: float, lam0: float, lam1: float
    ) -> tuple[Forcing | None, float]:
        """The compiled loop's forcing group for one call, and theta'' of its ramp.  With an unbalance,
        k at the start (``st.f``, in place) is moved to this call's theta'' (a ramp change is a jump of
        the angular acceleration, so the first step sees the new one at both of its ends)."""
        ub = st.unbalance
        if ub is None and not st.shocks:
            return None, st.rotation_acceleration
        rate = (lam1 - lam0) / span if span > 0 else st.rotation_acceleration
        u = 0.0 if ub is None else ub.magnitude
        angle = st.rotation_angle + (0.0 if ub is None else ub.phase_rad)
        if u != 0.0 and rate != st.rotation_acceleration:
            L = self.model.layout
            d = rate - st.rotation_acceleration
            st.f[L.xi_dot_index] -= u * d * math.cos(angle)
            st.f[L.eta_dot_index] += u * d * math.sin(angle)
        shocks = np.array([q.as_row() for q in st.shocks]) if st.shocks else _NO_SHOCKS
        lam_max = max(lam0, lam1)
        n_rev = self.options.steps_per_revolution
        max_step = math.inf if u == 0.0 or lam_max <= 0 else 2.0 * math.pi / (n_rev * lam_max)
        return Forcing(u, angle, shocks, max_step), rate

    def advance(
        self,
        tau_end: float,
        bearing_number: float | None = None,
        foil_damping: float | None = None,
        record_interval: float | None = None,
        record_indices: np.ndarray | None = None,
        max_steps: int = DEFAULT_MAX_STEPS,
        raise_on_failure: bool = True,
    ) -> AdvanceResult:
        """Integrate to ``tau_end`` with Lambda and D_W ramped linearly from their current values to
        ``bearing_number`` / ``foil_damping`` (unchanged when None).

        Records the rotor state, the min film thickness and ``record_indices`` (extra state entries,
        e.g. pressure probes from :meth:`StateLayout.midplane_probe_indices`) every
        ``record_interval`` (a uniform grid anchored at tau = 0, by cubic Hermite interpolation).

        Stops early on touchdown (``status == "touchdown"``, with the event).  If the step size falls
        below ``min_step`` or ``max_steps`` is exceeded, raises :class:`IntegrationError` (or returns
        ``status == "failed"`` / ``"max_steps"`` when ``raise_on_failure`` is False); the state is
        then the last accepted one, never NaN.

        Three parts: :meth:`prepare` (Python: checks and the compiled call's arguments), the compiled
        loop :func:`~gfb_env.integrator.stages._advance` (:meth:`_run`), :meth:`_finish` (Python: the
        new :class:`StepperState` and the result).  :class:`~gfb_env.integrator.BatchAdvance` runs the
        same parts for many integrators with one compiled call.
        """
        call = self.prepare(tau_end, bearing_number, foil_damping, record_interval, record_indices, max_steps)
        code, clock = self._run(call)
        return self._finish(
            call, code, clock, call.stats.tolist(), call.ext.tolist(), call.rec_buf, raise_on_failure
        )

    def _run(self, call: PreparedCall) -> tuple[int, tuple[float, float, float, float, int]]:
        """The compiled loop of one prepared call: its status code and clock at the end."""
        return _call_compiled(
            _advance, (self._factorization.size_tag, call.forcing is None),
            call.st.arrays, call.st.clock, call.schedule, self._kernel_args, self._jacobian,
            self._factorization, call.options, call.recording, call.stats, call.ext, call.forcing,
        )  # fmt: skip

    def _record_indices(self, record_indices: np.ndarray | None) -> np.ndarray:
        """The recorded state entries: the rotor, then ``record_indices`` (checked; the last one is
        kept, so an env that records the same probes every control step builds them once)."""
        extra = _NO_INDICES if record_indices is None else np.asarray(record_indices, np.int64)
        key = (extra.shape, extra.tobytes())
        if key == self._record_key:
            return self._record_idx
        if extra.size and (extra.min() < 0 or extra.max() >= self.model.layout.size):
            raise ValueError("record_indices out of range")
        L = self.model.layout
        rec_idx = np.concatenate([np.arange(L.rotor_offset, L.size, dtype=np.int64), extra])
        self._record_key, self._record_idx = key, rec_idx
        return rec_idx

    def prepare(
        self,
        tau_end: float,
        bearing_number: float | None,
        foil_damping: float | None,
        record_interval: float | None,
        record_indices: np.ndarray | None,
        max_steps: int,
    ) -> PreparedCall:
        """Check one call's arguments and build the compiled loop's (nothing is integrated yet; the
        unbalance's k at the start may move to this call's theta'', see :meth:`_forcing_of_call`)."""
        st = self._stepper
        lam0, dw0 = st.bearing_number, st.foil_damping
        lam1 = lam0 if bearing_number is None else float(bearing_number)
        dw1 = dw0 if foil_damping is None else float(foil_damping)
        self.model.check_operating_point(lam1, dw1)
        if not math.isfinite(tau_end):
            raise ValueError(f"tau_end must be finite, got {tau_end!r}")
        t0 = st.tau
        if tau_end < t0:
            raise ValueError(f"tau_end must not be before the current time {t0}, got {tau_end}")
        rec_idx = self._record_indices(record_indices)
        if record_interval is None:
            rec_dt = math.inf
            rec_next = math.inf
            cap = 0
        else:
            if not (math.isfinite(record_interval) and record_interval > 0):
                raise ValueError(f"record_interval must be positive, got {record_interval!r}")
            rec_dt = float(record_interval)
            # samples on the grid k * rec_dt, each recorded once across consecutive calls
            k0 = math.ceil(t0 / rec_dt - 1e-9)
            if k0 * rec_dt <= st.last_record_tau + 1e-9 * rec_dt:
                k0 += 1
            rec_next = k0 * rec_dt
            cap = max(int(math.floor((tau_end - rec_next) / rec_dt + 1e-9)) + 2, 0)
        rec_buf = np.empty((cap, len(rec_idx) + 2))
        first = 0
        if cap and rec_next <= t0 + 1e-9 * rec_dt:  # a sample exactly at the start
            rec_buf[0, 0] = t0
            rec_buf[0, 1:-1] = st.s[rec_idx]
            rec_buf[0, -1] = self.model.min_film_thickness(st.s)
            first = 1
            rec_next += rec_dt
        head = self._loop_options
        if self._growth is not None:
            if self._growth.settled(st.growth_window, (lam1, dw1)):
                head = self._settled_loop_options
            elif st.step > self.options.max_step:  # back from a settled limit: the proposal too
                st = self._stepper = dataclasses.replace(st, step=self.options.max_step)
        # the loop's options of (head, max_steps), kept from the last call (a namedtuple of 16 fields
        # built anew every control step otherwise; both are immutable)
        last = self._last_loop_options
        if last is not None and last[0] is head and last[1] is max_steps:
            options = last[2]
        else:
            options = LoopOptions(*head, int(max_steps))
            self._last_loop_options = (head, max_steps, options)
        span = float(tau_end) - t0
        forcing, rate = self._forcing_of_call(st, span, lam0, lam1)
        return PreparedCall(
            st=st,
            schedule=(float(tau_end), lam0, lam1, dw0, dw1),
            span=span,
            rate=rate,
            options=options,
            recording=Recording(rec_idx, rec_dt, float(rec_next), rec_buf[first:]),
            rec_buf=rec_buf,
            first=first,
            stats=np.zeros(9, dtype=np.int64),
            ext=_EXTREMES_START.copy(),
            forcing=forcing,
            max_steps=max_steps,
        )

    def _finish(
        self,
        call: PreparedCall,
        code: int,
        clock: tuple[float, float, float, float, int],
        counts: list[int],
        ext: list[float],
        rec_buf: np.ndarray,
        raise_on_failure: bool,
    ) -> AdvanceResult:
        """The integrator's new state and the call's result from the compiled loop's outputs: its status
        code, clock, counters and extremes (as lists) and its sample buffer (``call.rec_buf`` or the
        batch's copy of it)."""
        st = call.st
        t0, lam0, lam1, dw0, dw1 = st.tau, *call.schedule[1:]
        span = call.span
        t = float(clock[0])
        theta = (t - t0) / span if span > 0 else 1.0
        lam_t = lam0 + (lam1 - lam0) * theta
        dw_t = dw0 + (dw1 - dw0) * theta
        nrec = call.first + counts[_NREC]
        rb = rec_buf[:nrec]
        # theta' = Lambda is linear in time over the call: theta advances by the exact trapezoid
        angle = st.rotation_angle + (t - t0) * 0.5 * (lam0 + lam_t)
        window = ()
        if self._growth is not None:
            # the rotor's rate of motion at the end from (xi', eta', xi'', eta'') = k(s) of the rotor
            # rows: |v|^2 + |a|^2 / omega^2 with the whirl's frequency omega = 0.4 Lambda is the same at
            # every phase of a harmonic whirl (v = -A omega sin, a = -A omega^2 cos), so call ends at
            # different phases of a decaying orbit do not read as growth
            r0 = self.model.layout.rotor_offset
            # the four entries as floats: the same squares (libm's pow, as numpy's scalars take) and sums
            f0, f1, f2, f3 = st.f[r0 : r0 + 4].tolist()
            w2 = (WHIRL_FREQUENCY_RATIO * max(lam_t, 1e-3)) ** 2
            motion = math.sqrt(f0**2 + f1**2 + (f2**2 + f3**2) / w2)
            window = self._growth.window_after(st.growth_window, t, motion, (lam_t, dw_t))
        self._stepper = new = st.advanced(
            clock,
            bearing_number=lam_t,
            foil_damping=dw_t,
            counts=counts,
            last_record_tau=float(rb[-1, 0]) if nrec else st.last_record_tau,
            rotation_angle=math.fmod(angle, 2.0 * math.pi) if span > 0 else st.rotation_angle,
            rotation_acceleration=call.rate,
            shocks=tuple(q for q in st.shocks if q.end_tau > t) if st.shocks else (),
            growth_window=window,
        )
        # one copy of the samples, column by column (each column contiguous; the probes a view of it)
        cols = rb.T.copy()
        tau_s = cols[0]
        # the schedule at the samples, lam0 + (lam1 - lam0) th (th >= 0 finite); where the call holds
        # a positive value that is lam0 + 0.0 = lam0 exactly, filled without the arithmetic
        lam_held, dw_held = lam1 == lam0 and lam0 > 0.0, dw1 == dw0 and dw0 > 0.0
        if not (lam_held and dw_held):
            th = (tau_s - t0) / span if span > 0 else np.ones_like(tau_s)
        if lam_held:
            lam_s = np.empty(len(tau_s))
            lam_s.fill(lam0)
        else:
            lam_s = lam0 + (lam1 - lam0) * th
        if dw_held:
            dw_s = np.empty(len(tau_s))
            dw_s.fill(dw0)
        else:
            dw_s = dw0 + (dw1 - dw0) * th
        traj = Trajectory(
            tau=tau_s,
            xi=cols[1],
            eta=cols[2],
            xi_dot=cols[3],
            eta_dot=cols[4],
            min_film_thickness=cols[-1],
            probes=cols[5:-1].T,
            bearing_number=lam_s,
            foil_damping=dw_s,
        )
        event = None
        if code == _TOUCHDOWN:
            event = TouchdownEvent(ext[_EVT], ext[_EVXI], ext[_EVETA], self.options.touchdown_film_thickness)
        msg = ""
        if code == _FAILED:
            msg = (
                f"step size fell below min_step={self.options.min_step:g} at tau={t:.6g} "
                f"(Lambda={lam_t:.4g}, D_W={dw_t:.4g}); the state is the last accepted one"
            )
        elif code == _MAX_STEPS:
            msg = f"max_steps={call.max_steps} reached at tau={t:.6g}"
        min_h = ext[_MINH]
        if not math.isfinite(min_h):
            min_h = self.model.min_film_thickness(new.s)
        res = AdvanceResult(
            status=_STATUS_OF_CODE[code],
            tau=t,
            trajectory=traj,
            touchdown=event,
            statistics=IntegratorStatistics.from_counts(counts),
            min_film_thickness=float(min_h),
            xi_range=(ext[_XIMIN], ext[_XIMAX]),
            eta_range=(ext[_ETAMIN], ext[_ETAMAX]),
            max_eccentricity=ext[_EPSMAX],
            message=msg,
        )
        if raise_on_failure and code in (_FAILED, _MAX_STEPS):
            raise IntegrationError(msg)
        return res


# ------------------------------------------------------------------------------------------------
#: (compiled function, key) -> the entry point of its compiled variant for the argument types of that key
_ENTRY_POINTS: dict[tuple, Any] = {}


def _call_compiled(dispatcher: Any, key: tuple, *args: Any) -> Any:
    """``dispatcher(*args)``, the types of whose arguments ``key`` determines.  The first call of a key
    goes through numba's dispatcher (it compiles or loads the variant); later ones call that variant's
    entry point directly.  The dispatcher types every argument of every call, and the factorisation's
    ``size_tag`` tuple alone cost ~12 us of the ~22 us it spent on one control step's call (CPU time):
    the arguments' types here are fixed by the key (the block size and whether a forcing is passed
    for :func:`_advance`; the workspace's static part for :func:`_advance_batch`), the call is the same
    compiled code."""
    entry = _ENTRY_POINTS.get((dispatcher, key))
    if entry is not None:
        return entry(*args)
    result = dispatcher(*args)
    try:
        types = tuple(dispatcher.typeof_pyval(a) for a in args)
        _ENTRY_POINTS[(dispatcher, key)] = dispatcher.overloads[types].entry_point
    except (KeyError, AttributeError):  # pragma: no cover - numba without these internals: the dispatcher
        pass
    return result


def _shape_key(model: GFBModel) -> tuple:
    """What the stacked arrays' shapes and the solver's static arguments depend on."""
    g = model.grid
    return (
        model.layout.size,
        g.n_columns,
        g.n_rows,
        model.layout.block_size,
        model.sparse_offdiagonal_blocks,
    )
