"""The cause of a cell that did not come through, read from its record's numbers."""

from __future__ import annotations

from typing import Any

from dolfinx_invertible.reports.stability.study import CONTINUATION_STEP, REST

__all__ = ["CAUSES", "COLLAPSED", "CONVERGING", "KINK", "PINNED", "diagnose"]


def diagnose(record: dict[str, Any]) -> tuple[str, str]:
    """Return (cause class, one sentence with the numbers) of a cell's outcome.

    Classes of cells that came through: ``recovered``, ``completed``; of the others, see the
    module description and docs/stability.md.
    """
    outcome = record.get("outcome")
    if outcome in ("recovered", "completed"):
        return outcome, ""
    if outcome == "does_not_apply":
        return "does not apply", record.get("reason", "")
    if outcome == "timeout":
        return "timeout", record.get("reason", "")
    if outcome == "crashed":
        return "crashed", record.get("reason", "")
    if outcome == "nan":
        return "NaN", record.get("reason", "")
    if outcome in ("stalled_inverted", "not_at_rest"):
        runaway = _runaway(record)
        if runaway:
            return "energy below rest when inverted", runaway
        continued = record.get("continued")
        inverted = record.get("continued_inverted")
        distance = record.get("continued_rest_distance")
        overlap = record.get("continued_overlap")
        state = (
            f"{record.get('final_inverted')} inverted cells, rest distance "
            f"{_number(record.get('rest_distance'))} at t = {_number(record.get('t_end_star'))} "
            f"L/c (kinetic energy {_number(record.get('kinetic_final'))} E L³)"
        )
        largest = record.get("largest_singular_value")
        if continued == "completed" and largest is not None and largest < COLLAPSED:
            return (
                "collapsed equilibrium",
                f"{state}; every singular value is below {_number(largest)}: the body sits "
                "collapsed at F ≈ 0 and stays there when continued. For an energy of I_C and J "
                "such as stable Neo-Hookean, P = μF·I_C/(I_C + 1) + λ(J − α) cof F vanishes at "
                "F = 0 in 3D: the fully collapsed state is an equilibrium with no restoring force",
            )
        if continued == "completed" and inverted == 0 and distance is not None and distance < REST:
            return (
                "end time too short",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c it "
                f"recovers by t = {_number(record.get('continued_time'))} L/c",
            )
        settled = (
            f"the last continued step moved no node by more than "
            f"{_number(record.get('continued_last_motion'))} of the diameter in "
            f"{record.get('continued_last_newton')} Newton iterations"
        )
        negative = record.get("continued_tangent_negative")
        if continued == "completed" and inverted and negative:
            return (
                "inverted saddle",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c it stays at "
                f"{inverted} inverted cells ({settled}), but the exact tangent there has "
                f"{negative} negative eigenvalues (smallest "
                f"{_number(record.get('continued_tangent_min'))}, largest "
                f"{_number(record.get('continued_tangent_max'))}): a stationary point that is "
                "not a minimum, which Newton on the projected tangent does not leave",
            )
        if continued == "completed" and inverted:
            curvature = (
                f"; the exact tangent there is positive definite (smallest eigenvalue "
                f"{_number(record.get('continued_tangent_min'))})"
                if negative == 0
                else ""
            )
            return (
                "inverted equilibrium",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c (each a "
                f"near-static minimisation) it stays at {inverted} inverted cells (rest distance "
                f"{_number(distance)}, {overlap} cells inside others; {settled}){curvature}: a "
                "local minimum of the discrete energy with inverted elements",
            )
        if continued == "completed" and overlap:
            return (
                "self-overlapping equilibrium",
                f"{state}; continued it stays uninverted at rest distance {_number(distance)} "
                f"with {overlap} cells whose centroid lies inside another cell ({settled}): the "
                "body has passed through itself, a locally injective but tangled state that is "
                "a local minimum of the elastic energy (nothing in the model keeps a body from "
                "penetrating itself)",
            )
        if continued == "completed":
            return (
                "distorted equilibrium",
                f"{state}; continued it stays uninverted but at rest distance "
                f"{_number(distance)}, without self-overlap: an equilibrium away from the rest "
                "shape",
            )
        return "continuation failed", f"{state}; the continuation {continued}"
    if outcome == "failed":
        return _diagnose_failure(record)
    return str(outcome), record.get("reason", "")


#: |σ₂ + σ₃| / σ₁ below which an inverted point counts as on the kink.
KINK = 1.0e-3
#: Inversion-free cap below which a Newton step counts as pinned.
PINNED = 1.0e-3
#: Largest singular value below which a body counts as collapsed to a point.
COLLAPSED = 0.05
#: Residual reduction over the last ten iterations below which a capped solve was converging.
CONVERGING = 0.5


def _runaway(record: dict[str, Any]) -> str:
    """Describe a body that fell into inverted states below its rest energy, or return ''."""
    lowest = record.get("inverted_energy_min")
    if lowest is None or lowest >= 0.0:
        return ""
    distance = record.get("rest_distance")
    lowest_J = record.get("final_min_J")
    expanded = (distance is not None and distance > 1.0) or (
        lowest_J is not None and lowest_J < -1.0
    )
    if not expanded:
        return ""
    return (
        f"the material's energy is below its rest energy in inverted states (min (Ψ − Ψ(I))/μ "
        f"= {_number(lowest)} along F = diag(s, s, −s)), and the body fell into them: smallest "
        f"J {_number(lowest_J)}, rest distance {_number(distance)}, kinetic energy up to "
        f"{_number(record.get('kinetic_max'))} E L³"
        + (f"; then {record.get('failed_stage')} failed" if record.get("failed_stage") else "")
    )


def _diagnose_failure(record: dict[str, Any]) -> tuple[str, str]:
    runaway = _runaway(record)
    if runaway:
        return "energy below rest when inverted", runaway
    stage = record.get("failed_stage")
    where = (
        f"at t = {_number(record.get('failed_time_star'))} L/c, stage {stage} "
        f"({record.get('snes_reason')}"
        + (f", KSP {record.get('ksp_reason')}" if record.get("ksp_reason") else "")
        + ")"
    )
    gap = record.get("kink_gap")
    cap = record.get("cap_last")
    retry = record.get("retry")
    floor = record.get("step_floor")
    below_floor = (
        record.get("retry_step") is not None and floor is not None and record["retry_step"] < floor
    )
    ending = (
        "the controller then stopped at its step floor"
        if below_floor
        else "the controller then stopped after its 6 consecutive cuts"
    )
    if retry == "converged":
        ending += ", and one more cut converges"
    elif retry is not None:
        ending += f", and one more cut fails too ({retry})"
    # The retry that stopped at the iteration cap is run once more with a larger cap
    # (runner.LONG_SOLVE): does Newton get there with more iterations?
    long_retry = record.get("long_retry")
    if long_retry == "converged":
        ending += (
            f"; allowed more Newton iterations, that cut converges in "
            f"{_number(record.get('long_retry_iterations'))} iterations"
        )
    elif long_retry == "iteration cap":
        ending += "; allowed more Newton iterations, that cut stops at the larger cap too"
    elif long_retry is not None:
        ending += f"; allowed more Newton iterations, that cut fails ({long_retry})"
    # The spectrum is known on small problems only (runner.SPECTRUM_LIMIT).
    tangent = (
        f"; the exact tangent at the last iterate has {record.get('tangent_negative')} "
        f"negative eigenvalues, condition {_number(record.get('tangent_condition'))}"
        if record.get("tangent_negative") is not None
        else ""
    )
    drop = record.get("residual_drop_last10")
    if long_retry == "converged":
        falling = (
            f" (the failed attempt's residual × {_number(drop)} over its last 10 iterations)"
            if drop is not None
            else ""
        )
        return (
            "iteration cap",
            f"{where}; the cut step needs more Newton iterations than the attempt's budget "
            f"(its cap or its progress test){falling}{tangent}; {ending}",
        )
    if gap is not None and gap < KINK:
        return (
            "kink σ₂+σ₃=0",
            f"{where}; the last Newton iterate of the failed attempt has inverted points with "
            f"|σ₂ + σ₃|/σ₁ = {_number(gap)}: on the kink of the energy, where the stress "
            f"jumps; {ending}",
        )
    if cap is not None and cap < PINNED:
        return (
            "inversion-free cap stalls",
            f"{where}; the inversion-free cap limits the last Newton step to {_number(cap)} "
            f"(median {_number(record.get('cap_median'))}): the iterate is pinned against the "
            f"volume barrier; {ending}",
        )
    condition = record.get("tangent_condition")
    if stage == "linear solve" and condition is not None and condition > 1.0e12:
        return (
            "nearly singular tangent",
            f"{where}; the tangent at the last iterate has condition number "
            f"{_number(condition)}; {ending}",
        )
    if stage in ("iteration cap", "stalled") and drop is not None and drop < CONVERGING:
        return (
            "iteration cap while converging",
            f"{where}; Newton was converging linearly (residual × {_number(drop)} over the "
            f"last 10 iterations, × {_number(record.get('residual_drop'))} over the attempt) "
            f"but not within the iteration cap{tangent}; {ending}",
        )
    if retry == "converged":
        return ("step-size floor" if below_floor else "cut budget", f"{where}; {ending}")
    return (
        f"solver ({stage})",
        f"{where}; residual × {_number(drop)} over the last 10 iterations{tangent}; "
        f"inverted points {record.get('inverted_points')}; {ending}",
    )


def _number(value) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        if value == 0.0 or 1.0e-3 <= abs(value) < 1.0e4:
            return f"{value:.3g}"
        return f"{value:.2e}"
    return str(value)


#: What each cause class means, for the Markdown.
CAUSES = {
    "end time too short": "the relaxation was still untangling or still moving at the end "
    "time; continued with damped steps it recovers (methodological: the end time).",
    "inverted equilibrium": "continued with near-static damped steps the body stays with "
    "inverted cells: a local minimum of the discrete energy with inverted elements (physical "
    "for the discrete model).",
    "inverted saddle": "continued with near-static damped steps the body stays with inverted "
    "cells at a stationary point where the exact tangent has negative eigenvalues: not a "
    "minimum; Newton on the projected tangent converges to any stationary point (a solver "
    "limitation, not the energy's).",
    "distorted equilibrium": "continued, the body stays uninverted but away from its rest "
    "shape, without self-overlap: an equilibrium of the method that is not the rest state.",
    "collapsed equilibrium": "the body stays collapsed at F ≈ 0, a stationary point of the "
    "energy where the stress vanishes (stable Neo-Hookean in 3D): a property of the energy.",
    "self-overlapping equilibrium": "continued, the body stays uninverted but part of it lies "
    "inside another part: it passed through itself (no contact in the model), a tangled local "
    "minimum of the elastic energy.",
    "energy below rest when inverted": "the material's energy is lower in inverted states than "
    "at rest (Neo-Hookean + C1 at large λ/μ), so the released body falls into ever more "
    "expanded inverted states: a property of the energy, not of the solver.",
    "kink σ₂+σ₃=0": "the last Newton iterate of the failed step has inverted points on "
    "σ₂ + σ₃ = 0, where an energy of the signed singular values that is not even in each pair "
    "of them (corotated, fixed corotated) has a kink and its stress jumps: the step failed with "
    "its iterate there after the controller's cuts; the detail says what one more cut (and, "
    "where that stopped at the iteration cap or stalled, more iterations) gave.",
    "iteration cap": "the step failed, one more cut stopped at Newton's iteration cap or its "
    "progress test too, and the same cut allowed more iterations converges (in the number of "
    "iterations the detail gives): Newton gets there, in more iterations than its budget.",
    "iteration cap while converging": "the failed attempt stopped at Newton's iteration "
    "cap with its residual still falling (to less than half over its last 10 iterations), "
    "and a retry allowed more iterations was not run or did not converge.",
    "cut budget": "the controller gave up after 6 consecutive cuts; one more cut converges.",
    "inversion-free cap stalls": "the inversion-free cap limits every Newton step to nearly "
    "zero: the iterate is pinned against the volume barrier.",
    "step-size floor": "the controller cut the step to its floor (dt/4096) and one more cut "
    "converges: the solution moves through a region Newton resolves only with tiny steps.",
    "nearly singular tangent": "the tangent at the last iterate is numerically singular.",
    "does not apply": "plain Neo-Hookean cannot start from inverted cells.",
}
