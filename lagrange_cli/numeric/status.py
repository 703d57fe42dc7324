"""How a run ends and what it counted: the codes shared by the compiled loops and Python, defined once.

The kernels (kernels.py, compiled by numba) return the integer codes below and fill a float64
counter array indexed by the counter constants; the Python side turns both into `Status` and
`integrators.Stats` by name. This module imports nothing (no numba, no numpy), so that every
layer can use it.

As in scipy's `OdeSolver` (a status and named counters, never a message parsed back), a run's
outcome is a `Status`; a measured point of a study that did not finish says why by a `Failure`.
"""

from __future__ import annotations

import enum

# -- codes returned by the compiled loops (plain ints: numba reads them as compile-time constants)
RUNNING = -1
"""Paused: at t_stop, or after PAUSE_STEPS steps; call again."""
DONE = 0
EVENT = 1
SINGULAR = 2
NONFINITE = 3
STEP_COLLAPSE = 4
NO_CONVERGENCE = 5
BUDGET = 6
"""The driver's own: the step budget ran out (never returned by a kernel)."""

PAUSE_STEPS = 20000
"""A loop returns RUNNING after this many steps even before t_stop, so that the caller can report
progress and stop a run over its budget (a near-collision orbit may take minutes of 1e-10 s steps
to reach the first 1% of its time span)."""

# -- the counter array `stats` of a compiled loop (float64, STATS_SIZE entries)
NFEV, NJEV, NSTEPS, NREJECT, HMIN, HMAX, STIFF, NONSTIFF, H_LAMBDA, NLU, FLOORED = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10
"""Right-hand side evaluations, Jacobians (the Gauss method: its Newton matrices), steps taken,
rejected steps, smallest and largest step; DOP853's stiffness test where it is asked for
(control[STIFFNESS]): the positive tests since the last run of STIFF_RESET negative ones, the
negative ones in a row, and the last h |lambda| measured; the LU decompositions (the compiled Radau
method: its real and complex Newton matrices count one each); the compiled Radau method's steps
accepted with the scale of its error test raised to the round-off floor (kernels._radau_floor)."""
STATS_SIZE = 11

# -- the loop state `state` (float64): where a paused loop resumes
T, H, EVENT_VALUE, NEXT_SAMPLE, NEWTON = 0, 1, 2, 3, 4
"""The time reached; the next step size (explicit pairs) or the steps done (Gauss); the stop
condition's value at t; the index of the next sample to write; 1.0 while the Gauss method's
Newton matrix (kept by the caller) is current."""
STATE_SIZE = 5

# -- the controls `control` of a loop (float64; read-only to the loops)
RTOL, ATOL, MAX_STEP, T_BOUND, T_STOP, USE_EVENT, SIZE, STEP, STEPS, T0, STIFFNESS, STRETCH, ANALYTIC = range(13)
"""Tolerances and the largest step (explicit pairs); the end of the run and where to pause; 1.0
when a stop condition is watched; the size of the system's workspace (coordinates and
multipliers); the fixed step, the number of steps and the start (Gauss); 1.0 to run DOP853's
stiffness test and pause (RUNNING) once it finds the problem stiff (0: no test, the default); the
steps an explicit pair takes before it pauses (0: PAUSE_STEPS, the default); 1.0 when the compiled Radau
method is given the system's analytic Jacobian (`_jac`; 0: forward differences)."""
CONTROL_SIZE = 13

# -- the projection record `record` of a projected explicit run (kernels.erk_projected; float64)
LEVEL, USE_LEVEL, NEWTON_LIMIT, ROUND_OFF_LEVEL, ENERGY_LIMIT, CONDITION_LIMIT, CHANGE_LIMIT = range(7)
"""Inputs: the energy level h0 and 1.0 to project onto it too (a conserved energy); projection.py's
constants NEWTON_STEPS, ROUND_OFF, ENERGY_STEPS, ENERGY_CONDITION and ENERGY_CHANGE (passed in, so
that the compiled projection and `projection.Projector` cannot differ in them)."""
NEXT_BOUND, POSITION, VELOCITY, MOVED, ENERGY, PROJECTIONS, FAILURES, FAILED_AT = range(7, 15)
"""The loop's own state: the index of the next projection time. What it reports: the largest
residuals corrected (max |f(q, t)| of the holonomic rows before the position step, max |a . q_dot + b|
before the velocity step, the largest change of any component, |h - h0| before the energy step), the
projections made, those that could not be applied (A M^-1 A^T singular, or values not finite: the
state is kept as it was), and the time of the first of those (NaN: none)."""
PROJECTION_SIZE = 15

# -- what the compiled Radau method (kernels.radau_run) carries from one call to the next (`memory`, float64)
T_OLD, STEP_OLD, H_ABS_OLD, ERROR_OLD, CURRENT_JAC, LU_STEP, HAVE_DENSE, CONTRACTION = range(8)
"""The start and the (signed) size of the last accepted step, whose collocation polynomial (the dense
output) predicts the next step's stages; the step size the step before began from and its error norm
(NaN: none; the predictive step control's memory); 1.0 while the Jacobian is the one at the current
state; the step size the Newton matrices were factored for (0.0: none: they are refactored), and 1.0
once a step has been taken (a dense output exists); the Newton iteration's last contraction factor
rate / (1 - rate) (radau5.f's FACCON), with which a step's first correction can already be judged."""
RADAU_SIZE = 8

# -- DOP853's stiffness test (Hairer and Wanner, dop853.f): on an accepted step, h |lambda| is
# estimated from the last stage and the new solution, both at t + h: h |f(y_new) - f(Y_12)| / |y_new - Y_12|
STIFF_H_LAMBDA = 6.1
"""h |lambda| above which a step counts as limited by stability (DOP853's region reaches about 6 on the negative real axis)."""
STIFF_STEPS = 15
"""Positive tests (without STIFF_RESET negative ones in a row between them) that make the problem stiff."""
STIFF_RESET = 6
"""Negative tests in a row that clear the count of positive ones."""

# -- step-size control of the explicit pairs (scipy's values)
SAFETY = 0.9
"""The new step is SAFETY x the step that would make the error estimate exactly 1."""
MIN_FACTOR = 0.2
"""A step never shrinks by more than this factor at once."""
MAX_FACTOR = 10.0
"""... nor grows by more than this one."""
MIN_STEP_SPACINGS = 10.0
"""The step collapses below this many floating-point spacings of t."""
FLOOR_SAFETY = 10.0
"""The compiled Radau method's error test asks no component for less than this x the round-off in
its error estimate (kernels._radau_floor)."""


class Status(enum.StrEnum):
    """How a run ended (a `str`, so that `run.status == "finished"` reads as before)."""

    FINISHED = "finished"
    EVENT = "event"
    SINGULAR = "singular"
    NONFINITE = "nonfinite"
    STEP_COLLAPSE = "step"
    SURFACE_JUMP = "jump"
    """The run stopped on a switching surface where the forces jump (`simulate._on_surface`): a sliding mode (the
    field on both sides pointing into the surface, as dry friction where a body sticks: the loops stop after CHATTER
    quick crossings in a row; the scipy loop also where Filippov's condition holds, integrators._Switches.attracting),
    or through scipy a step size that collapsed there (the compiled loops hop
    across such a jump, kernels._hop). Not a blow-up; through scipy a looser tolerance may pass it."""
    NO_CONVERGENCE = "convergence"
    BUDGET = "budget"
    STALLED = "stalled"
    """The run's steps shrank until its budget ran out (or below round-off) at a state where the mass matrix is
    nearly singular, far more so than at the start (`simulate._stalled`): the coordinates end there (the bob of a
    pendulum written in x, y with z = -sqrt(L^2 - x^2 - y^2) reaching the pivot's height; Euler angles at gimbal
    lock). Not a blow-up of the motion; no method, tolerance or budget passes it, other coordinates do."""

    @classmethod
    def of_code(cls, code: int) -> Status:
        """The status of a kernel's (or a driver's) return code."""
        return _BY_CODE[code]

    @property
    def failed(self) -> bool:
        return self not in (Status.FINISHED, Status.EVENT)


QUICK_STEPS = 2
CHATTER = 8
"""CHATTER crossings in a row, each at most QUICK_STEPS accepted steps after the one before, are a sliding mode: the
forces jump across the surface and the field on both sides points into it (dry friction sign(v) where the block
sticks), so every restart crosses back at once. Filippov's solution slides along the surface, which the loops (the compiled ones and
integrators.run_scipy) do not follow: it stops there (STEP_COLLAPSE, which `simulate` reports as a jump on a switching surface), after a
number of steps, not at the step budget. A contact resolved at all lasts more than QUICK_STEPS steps."""
RADAU_QUICK_STEPS, RADAU_CHATTER = 4, 64
"""QUICK_STEPS and CHATTER for compiled Radau: after each landing in a sliding mode its implicit steps take 3 or 4 accepted
steps before they cross back, not 1 or 2, so at QUICK_STEPS no 8 crossings were in a row: dry friction where the block
sticks to the belt (audit 8's stick-slip block) crossed 412589 times in 1e6 steps, 16 s, to stop at the step budget. With
that window, 8 crossings in a row are also a ball rattling on a penalty wall (audit 6's ball in a cup at rtol 1e-5, a
false sliding mode at t = 0.425); 64 in a row are not: the block stops after 205 steps, the ball (215 crossings) finishes
at every rtol from 1e-3 to 1e-10."""


_BY_CODE = {
    DONE: Status.FINISHED,
    EVENT: Status.EVENT,
    SINGULAR: Status.SINGULAR,
    NONFINITE: Status.NONFINITE,
    STEP_COLLAPSE: Status.STEP_COLLAPSE,
    NO_CONVERGENCE: Status.NO_CONVERGENCE,
    BUDGET: Status.BUDGET,
}


class Failure(enum.StrEnum):
    """Why a measured run of a study did not give an error: the run's own failure, or the study's
    verdict on it (over its step budget, stopped by the time limit, not applicable)."""

    SINGULAR = "singular"
    NONFINITE = "nonfinite"
    """Infinite or NaN values, or a function that cannot be evaluated along the way."""
    STEP_COLLAPSE = "step"
    SURFACE_JUMP = "jump"
    """The run stopped on a switching surface where the forces jump (Status.SURFACE_JUMP)."""
    NO_CONVERGENCE = "convergence"
    BUDGET = "budget"
    STALLED = "stalled"
    """The run stalled where the coordinates end (Status.STALLED)."""
    TIME_LIMIT = "time limit"
    NOT_APPLICABLE = "not applicable"

    @classmethod
    def of(cls, status: Status) -> Failure | None:
        """The failure of a run's status (None when it finished or stopped at its event)."""
        return None if not status.failed else cls(status.value)
