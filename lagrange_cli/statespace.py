"""State-space linearization with inputs and outputs (FORMAT.md version 2, "Linearization").

About an operating point (q0, u0) that is an equilibrium (q_dot = 0, accelerations zero at u0):

    x = [q - q0, q_dot],  du = u - u0,  dx/dt = A x + B du,  y - y0 = C x + D du

Built on `analysis.linearize` (the model with u = u0): M0 x_ddot + C0 x_dot + K0 x = G du, with
G = T^T dF/du (T the tangent of kept holonomic constraints, identity without), so that

    A = [[0, I], [-M0^-1 K0, -M0^-1 C0]],  B = [[0], [M0^-1 G]],
    C = [dh/dq T, dh/dq_dot T],  D = dh/du     (h the outputs, all at (q0, 0, u0)).

The multipliers drop out of the reduced equations (T^T A0^T = 0), and the inputs are never
differentiated (the frontend refuses a file whose equations would hold u_dot), so A holds no
u_dot terms. Matrices are symbolic where feasible (at most `SYMBOLIC_MAX_N` independent
coordinates), numeric always (at the parameters' values).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from lagrange_cli.errors import DerivationError
from lagrange_cli.model import Model

SYMBOLIC_MAX_N = 4
"""Largest number of independent coordinates for which A and B are inverted symbolically."""


@dataclass(frozen=True)
class StateSpace:
    """The matrices of dx/dt = A x + B du, y - y0 = C x + D du; `numeric` holds them as floats at
    the parameters' values (None for a parameter without one), `symbolic` as sympy matrices (None
    for A and B beyond `SYMBOLIC_MAX_N` coordinates)."""

    about: Mapping[str, sp.Expr]
    state: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    symbolic: Mapping[str, sp.Matrix | None]
    numeric: Mapping[str, tuple[tuple[float, ...], ...]] | None
    y0: tuple[sp.Expr, ...] = ()
    controllability_rank: int | None = None
    notes: tuple[str, ...] = ()
    values: Mapping[str, float] = field(default_factory=dict)

    def arrays(self) -> dict[str, object]:
        """A, B, C, D as numpy arrays (the Python API)."""
        import numpy as np

        if self.numeric is None:
            raise DerivationError("the state-space matrices need every parameter's value: give the missing ones (e.g. `--set` or `parameters:` defaults)")
        return {key: np.array(value, dtype=float).reshape(_shape(self, key)) for key, value in self.numeric.items()}


def _shape(ss: StateSpace, key: str) -> tuple[int, int]:
    n, m, r = len(ss.state), len(ss.inputs), len(ss.outputs)
    return {"A": (n, n), "B": (n, m), "C": (r, n), "D": (r, m)}[key]


def state_space(model: Model, point: Mapping[sp.Symbol, sp.Expr], given: Mapping[str, sp.Expr] | None = None, values: Mapping[str, float] | None = None) -> StateSpace:
    """The state-space linearization about the coordinates `point` (others 0) and the inputs
    `given` (others at their default). Not an equilibrium: `DerivationError` with the residual."""
    from lagrange_cli import analysis, inputs

    given = dict(given or {})
    u0 = {i.symbol: sp.sympify(given[i.name]) if i.name in given else sp.nsimplify(i.value) for i in model.inputs}
    at_u0 = inputs.substitute(model, {str(s): v for s, v in u0.items()})
    try:
        lin = analysis.linearize(at_u0, point, values)
    except DerivationError as error:
        if u0 and "not an equilibrium" in str(error):
            shown = ", ".join(f"{s} = {v}" for s, v in u0.items())
            raise DerivationError(f"{error} (with the inputs at {shown})") from None
        raise
    if lin.velocities:
        raise DerivationError(f"{model.source}: a state-space linearization with velocity constraints is not available (their reduced state is not [q - q0, q_dot]); eliminate or drop them")
    if lin.stability.startswith("degenerate"):
        raise DerivationError(f"{model.source}: the mass matrix is singular at this point, so the accelerations (and A, B) are not defined there")
    general = model.with_definitions()
    q0 = {q: sp.sympify(lin.point.get(q, 0)) for q in general.q}
    full = {**q0, **{v: sp.Integer(0) for v in general.qd}, **u0}
    names = lin.coordinates or general.coordinates
    tangent = _tangent(general, names, lin.dependent)
    k = len(names)
    signals = [i.symbol for i in general.inputs]
    forcing_u = sp.Matrix(general.n, len(signals), lambda i, j: analysis.at(sp.diff(general.forcing[i], signals[j]), full))
    g = (tangent.T * forcing_u).applyfunc(analysis.simplified)
    outputs = [e for _, e in general.outputs]
    h_q = sp.Matrix(len(outputs), general.n, lambda i, j: analysis.at(sp.diff(outputs[i], general.q[j]), full))
    h_v = sp.Matrix(len(outputs), general.n, lambda i, j: analysis.at(sp.diff(outputs[i], general.qd[j]), full))
    c = sp.Matrix.hstack(h_q * tangent, h_v * tangent).applyfunc(analysis.simplified) if outputs else sp.zeros(0, 2 * k)
    d = sp.Matrix(len(outputs), len(signals), lambda i, j: analysis.simplified(analysis.at(sp.diff(outputs[i], signals[j]), full)))
    y0 = tuple(analysis.simplified(analysis.at(e, full)) for e in outputs)
    symbolic: dict[str, sp.Matrix | None] = {"A": None, "B": None, "C": c, "D": d}
    if k <= SYMBOLIC_MAX_N:
        inverse = lin.mass.inv().applyfunc(analysis.simplified)
        symbolic["A"] = _a_matrix(-inverse * lin.stiffness, -inverse * lin.damping).applyfunc(analysis.simplified)
        symbolic["B"] = sp.Matrix.vstack(sp.zeros(k, len(signals)), inverse * g).applyfunc(analysis.simplified)
    numbers = dict(values if values is not None else general.parameter_values())
    numeric = _numeric(general, numbers, lin, g, c, d)
    notes = _notes(general, names, numeric, g)
    rank = _rank(numeric) if numeric is not None and signals else (0 if not signals else None)
    about = {**{str(q): v for q, v in q0.items()}, **{str(s): v for s, v in u0.items()}}
    state = (*names, *(f"{n}_dot" for n in names))
    return StateSpace(about, state, tuple(map(str, signals)), tuple(n for n, _ in general.outputs), symbolic, numeric, y0, rank, notes, numbers)


def _tangent(model: Model, names: Sequence[str], dependent: Sequence[tuple[str, sp.Expr]]) -> sp.Matrix:
    """T with dq = T dz, z the independent coordinates `names` (identity without constraints)."""
    dz = [sp.Symbol(f"d{c}") for c in names]
    rows = {f"d{c}": expr for c, expr in ((c[1:], e) for c, e in dependent)}
    tangent = sp.zeros(model.n, len(names))
    for j, c in enumerate(model.coordinates):
        if c in names:
            tangent[j, list(names).index(c)] = 1
        else:
            expr = rows.get(f"d{c}", sp.Integer(0))
            for i, s in enumerate(dz):
                tangent[j, i] = sp.diff(expr, s)
    return tangent


def _a_matrix(stiff: sp.Matrix, damp: sp.Matrix) -> sp.Matrix:
    k = stiff.rows
    return sp.Matrix.vstack(sp.Matrix.hstack(sp.zeros(k, k), sp.eye(k)), sp.Matrix.hstack(stiff, damp))


def _numeric(model: Model, numbers: Mapping[str, float], lin: object, g: sp.Matrix, c: sp.Matrix, d: sp.Matrix) -> dict[str, tuple[tuple[float, ...], ...]] | None:
    import numpy as np

    table = {p.symbol: sp.Float(numbers[p.name]) for p in model.parameters if p.name in numbers}

    def array(matrix: sp.Matrix) -> np.ndarray | None:
        if matrix.rows == 0 or matrix.cols == 0:
            return np.zeros((matrix.rows, matrix.cols))
        try:
            return np.array(matrix.xreplace(table).evalf(), dtype=float)
        except (TypeError, ValueError):
            return None

    mass, damping, stiffness = (array(getattr(lin, name)) for name in ("mass", "damping", "stiffness"))
    gn, cn, dn = array(g), array(c), array(d)
    if any(x is None for x in (mass, damping, stiffness, gn, cn, dn)):
        return None
    assert mass is not None and damping is not None and stiffness is not None and gn is not None
    k = mass.shape[0]
    a = np.block([[np.zeros((k, k)), np.eye(k)], [-np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)]])
    b = np.vstack([np.zeros((k, gn.shape[1])), np.linalg.solve(mass, gn) if gn.shape[1] else np.zeros((k, 0))])

    def rows(x: np.ndarray) -> tuple[tuple[float, ...], ...]:
        return tuple(tuple(float(v) + 0.0 for v in row) for row in x)

    return {"A": rows(a), "B": rows(b), "C": rows(cn), "D": rows(dn)}  # type: ignore[arg-type]


def _rank(numeric: Mapping[str, tuple[tuple[float, ...], ...]]) -> int:
    """The rank of the controllability matrix [B, AB, ..., A^(n-1) B]."""
    import numpy as np

    a, b = np.array(numeric["A"], dtype=float), np.array(numeric["B"], dtype=float)
    n = a.shape[0]
    blocks, power = [], b
    for _ in range(n):
        blocks.append(power)
        power = a @ power
    matrix = np.hstack(blocks)
    scale = max(1.0, float(np.abs(matrix).max()))
    return int(np.linalg.matrix_rank(matrix, tol=1e-9 * scale * max(matrix.shape)))


def _notes(model: Model, names: Sequence[str], numeric: Mapping[str, tuple[tuple[float, ...], ...]] | None, g: sp.Matrix) -> tuple[str, ...]:
    """What sympy's Linearizer users trip over, said plainly."""
    notes = []
    if not model.inputs:
        notes.append("the file declares no `inputs`, so B and D have no columns: declare actuator forces under `inputs:` and use them in `forces`, a particle's `force` or the potential")
    else:
        for j, i in enumerate(model.inputs):
            if all(g[r, j] == 0 for r in range(g.rows)):
                notes.append(f"input '{i.name}' does not act on the state at this point (its column of B is zero)")
    if not model.outputs:
        notes.append("the file declares no `outputs`, so C and D have no rows: add e.g. `outputs: {" + (names[0] if names else "q") + ": " + (names[0] if names else "q") + "}`")
    return tuple(notes)


def lqr(ss: StateSpace, q: Sequence[float] | None = None, r: Sequence[float] | None = None) -> tuple[tuple[float, ...], ...]:
    """The LQR gain K (du = -K x) minimising the integral of x^T Q x + du^T R du, with Q and R
    diagonal (`q`, `r`: one weight per state and per input, or one weight for all; default 1),
    from the continuous algebraic Riccati equation (scipy)."""
    import numpy as np
    from scipy.linalg import solve_continuous_are

    if ss.numeric is None:
        raise DerivationError("an LQR gain needs every parameter's value")
    a, b = np.array(ss.numeric["A"], dtype=float), np.array(ss.numeric["B"], dtype=float).reshape(len(ss.state), len(ss.inputs))
    n, m = a.shape[0], b.shape[1]
    if m == 0:
        raise DerivationError("an LQR gain needs inputs: the file declares none (B has no columns)")
    weights_q = _weights(q, n, "Q", ss.state)
    weights_r = _weights(r, m, "R", ss.inputs)
    if ss.controllability_rank is not None and ss.controllability_rank < n:
        raise DerivationError(f"no LQR gain: the linearization is not controllable (controllability rank {ss.controllability_rank} < {n} states)")
    try:
        p = solve_continuous_are(a, b, np.diag(weights_q), np.diag(weights_r))
    except (np.linalg.LinAlgError, ValueError) as error:
        raise DerivationError(f"no LQR gain: the Riccati equation has no stabilising solution ({error})") from None
    gain = np.linalg.solve(np.diag(weights_r), b.T @ p)
    return tuple(tuple(float(v) for v in row) for row in gain)


def _weights(given: Sequence[float] | None, size: int, what: str, names: Sequence[str]) -> list[float]:
    import math

    if not given:
        return [1.0] * size
    values = list(given) * size if len(given) == 1 else list(given)
    if len(values) != size:
        raise DerivationError(f"{what} needs {size} weight(s), one per {'state' if what == 'Q' else 'input'} ({', '.join(names)}), or one for all; got {len(given)}")
    if any(not math.isfinite(v) or v < 0 or (what == "R" and v == 0) for v in values):
        raise DerivationError(f"the weights of {what} must be finite and " + ("positive" if what == "R" else "non-negative"))
    return values


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _rows_text(rows: tuple[tuple[float, ...], ...]) -> str:
    return "[" + ", ".join("[" + ", ".join(_fmt(v) for v in row) + "]" for row in rows) + "]"


def text(ss: StateSpace, gain: tuple[tuple[float, ...], ...] | None = None) -> str:
    """The state space as plain text: symbolic matrices where available, then numeric ones."""
    about = ", ".join(f"{k} = {v}" for k, v in ss.about.items())
    lines = [f"state space about {about} (rates zero): dx/dt = A x + B du, y - y0 = C x + D du"]
    lines.append(f"  x = [{', '.join(ss.state)}] (perturbations of the coordinates, and their rates)")
    lines.append(f"  du = [{', '.join(ss.inputs)}] (minus their values at the point)" if ss.inputs else "  du = [] (no inputs)")
    lines.append(f"  y = [{', '.join(ss.outputs)}], y0 = [{', '.join(map(str, ss.y0))}]" if ss.outputs else "  y = [] (no outputs)")
    for key in "ABCD":
        matrix = ss.symbolic.get(key)
        if matrix is not None and not all(e.is_number for e in matrix):
            lines.append(f"  {key} = {matrix.tolist()}")
    if ss.numeric is not None:
        lines.append("  at the parameters' values:")
        lines += [f"    {key} = {_rows_text(ss.numeric[key])}" for key in "ABCD"]
    else:
        lines.append("  (no numeric matrices: a parameter has no value)")
    if ss.controllability_rank is not None:
        lines.append(f"  controllability rank: {ss.controllability_rank} of {len(ss.state)}" + (" (controllable)" if ss.controllability_rank == len(ss.state) else " (not controllable)"))
    if gain is not None:
        lines.append(f"  LQR gain K (du = -K x): {_rows_text(gain)}")
    lines += [f"  note: {n}" for n in ss.notes]
    return "\n".join(lines) + "\n"


def latex(ss: StateSpace) -> str:
    """The four matrices in LaTeX (symbolic where available, else numeric)."""
    parts = []
    for key in "ABCD":
        matrix = ss.symbolic.get(key)
        if matrix is None and ss.numeric is not None:
            matrix = sp.Matrix(ss.numeric[key]) if ss.numeric[key] else sp.zeros(*_shape(ss, key))
        if matrix is None:
            continue
        body = sp.latex(matrix) if matrix.rows and matrix.cols else r"\text{(empty)}"
        parts.append(f"{key} = {body}")
    return "\\begin{gather}\n" + " \\\\\n".join(parts) + "\n\\end{gather}\n"


def as_json(ss: StateSpace, gain: tuple[tuple[float, ...], ...] | None = None) -> dict[str, object]:
    """The keys of FORMAT.md version 2: A, B, C, D (rows of numbers), state, inputs, outputs, about."""
    if ss.numeric is None:
        raise DerivationError("the state-space matrices need every parameter's value for --json: give the missing ones a value under `parameters:`")
    data: dict[str, object] = {key: [list(row) for row in ss.numeric[key]] for key in "ABCD"}
    data.update(
        state=list(ss.state),
        inputs=list(ss.inputs),
        outputs=list(ss.outputs),
        about={k: float(sp.N(v)) for k, v in ss.about.items()},
        controllability_rank=ss.controllability_rank,
        symbolic={key: [[str(e) for e in row] for row in m.tolist()] for key, m in ss.symbolic.items() if m is not None},
    )
    if ss.notes:
        data["notes"] = list(ss.notes)
    if gain is not None:
        data["lqr_gain"] = [list(row) for row in gain]
    return data


COMPARE_DRAWS = 3
"""Random parameter values (besides the defaults) at which an expected matrix entry is compared."""


def compare(model: Model, expected: Any) -> tuple[bool, str]:
    """Check `expect.state_space` (an `inputs.ExpectedStateSpace`): each given matrix has the
    derived shape and each entry equals the derived one, symbolically when the derived matrix is
    symbolic (compared at the defaults and at `COMPARE_DRAWS` random positive parameter values),
    else at the parameters' values. (passed, what differs)."""
    import random

    names = {str(q): q for q in model.q}
    point = {names[k]: v for k, v in expected.about if k in names}
    given = {k: v for k, v in expected.about if k not in names}
    ss = state_space(model, point, given)
    rng = random.Random(7)
    draws = [dict(ss.values)] + [{p.name: rng.uniform(0.5, 2.0) if not p.real else rng.uniform(-1.5, 1.5) for p in model.parameters} for _ in range(COMPARE_DRAWS)]
    for key, rows, _ in expected.matrices:
        shape = _shape(ss, key)
        got = (len(rows), len(rows[0]) if rows else shape[1])
        if got != shape:
            return False, f"{key} is {got[0]}x{got[1]} but the linearization's is {shape[0]}x{shape[1]} (x = [{', '.join(ss.state)}], du = [{', '.join(ss.inputs)}], y = [{', '.join(ss.outputs)}])"
        derived = ss.symbolic.get(key)
        for i, row in enumerate(rows):
            for j, entry in enumerate(row):
                if derived is not None:
                    for values in draws:
                        if len(values) < len(model.parameters):
                            continue
                        table = {p.symbol: sp.Float(values[p.name]) for p in model.parameters}
                        a, b = complex(sp.N(entry.xreplace(table))), complex(sp.N(derived[i, j].xreplace(table)))
                        if abs(a - b) > 1e-8 * (1 + abs(b)):
                            return False, f"{key}[{i + 1}][{j + 1}]: expected {entry}, derived {derived[i, j]}"
                elif ss.numeric is not None:
                    table = {p.symbol: sp.Float(ss.values[p.name]) for p in model.parameters if p.name in ss.values}
                    a, b = complex(sp.N(entry.xreplace(table))), ss.numeric[key][i][j]
                    if abs(a - b) > 1e-8 * (1 + abs(b)):
                        return False, f"{key}[{i + 1}][{j + 1}]: expected {entry} = {a.real:.6g}, derived {b:.6g} at the parameters' values"
                else:
                    return False, f"{key} cannot be compared: the system is too large for symbolic matrices and a parameter has no value"
    return True, ""
