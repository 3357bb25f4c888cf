"""Whether a fit can be trusted: it converged, and the signals tell each fitted parameter.

**Did not converge** (exit status 3), where any of these holds:

- the final least squares stopped at ``--max-evaluations`` before its tolerances were met,
  with a signal's RMS residual above 1.5 times its noise (below, it has come as close as the
  recording tells: a recording without noise, which it would follow ever closer);
- a fitted value ended at one of its bounds (the minimum may lie beyond it, or the fit was
  pushed there by a parameter it cannot tell);
- the fit leaves a signal's residual above ``RESIDUAL_LIMIT`` times its noise (the noise told
  from the recording itself, :mod:`.noise`, and at least ``FLOOR`` of the signal's range): the
  re-simulation does not follow the recording, a false minimum, or a parameter not fitted
  that is off.

**Not identifiable** (exit status 4, before 3), where any of these holds for a parameter:

- its interval is infinite (a direction the signals do not see), reaches outside the
  parameter's bounds (non-physical values such as a negative diameter), or is wider than the
  value itself (its half-width above its magnitude);
- it is correlated with another fitted parameter beyond ``CORRELATION_LIMIT``: the signals
  tell only a combination of the two;
- another start ended as well (its weighted sum of squares within the 95 % chi-square
  quantile, in units of the best fit's residual variance) outside the interval: two
  answers fit the recording equally.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: A fit leaving a signal's RMS residual above this many times its noise did not converge ...
RESIDUAL_LIMIT = 3.0
#: ... where that is also above this fraction of the signal's range.
FLOOR = 1e-3
#: Two fitted parameters correlated beyond this are not told apart.
CORRELATION_LIMIT = 0.999
#: Exit statuses of boom-calibrate for a fit that did not converge, and for one that cannot
#: tell a fitted parameter.
NOT_CONVERGED, NOT_IDENTIFIABLE = 3, 4


@dataclass(frozen=True)
class Finding:
    """Why a fit cannot be trusted: ``kind`` NOT_CONVERGED or NOT_IDENTIFIABLE, ``subject`` the
    parameter or signal it is about, ``why`` in words."""

    kind: int
    subject: str
    why: str

    @property
    def label(self) -> str:
        return "did not converge" if self.kind == NOT_CONVERGED else "not identifiable"


@dataclass(frozen=True)
class End:
    """Where one start of a fit ended."""

    start: dict[str, float]
    end: dict[str, float]
    cost: float  # its weighted sum of squares (the best fit's units)


def exit_status(findings: Sequence[Finding]) -> int:
    """4 if a parameter is not identifiable, else 3 if the fit did not converge, else 0."""
    kinds = {f.kind for f in findings}
    return NOT_IDENTIFIABLE if NOT_IDENTIFIABLE in kinds else NOT_CONVERGED if NOT_CONVERGED in kinds else 0


def _g(x: float) -> str:
    return f"{x:.4g}"


def convergence(
    stopped_at_limit: bool,
    at_bound: Mapping[str, bool],
    fitted: Mapping[str, float],
    rms: Mapping[str, float],
    noise: Mapping[str, float],
    ranges: Mapping[str, float],
    units: Mapping[str, str],
) -> list[Finding]:
    """The findings of a fit that did not converge (see the module docstring)."""
    found = []
    above = [s for s, value in rms.items() if not value <= 1.5 * noise[s]]
    if stopped_at_limit and above:
        found.append(Finding(NOT_CONVERGED, "least squares", "it stopped at --max-evaluations before it converged"))
    for name, bound in at_bound.items():
        if bound:
            found.append(Finding(NOT_CONVERGED, name, f"it ended at its bound ({_g(fitted[name])})"))
    for s, value in rms.items():
        limit = RESIDUAL_LIMIT * max(noise[s], FLOOR * ranges[s])
        if not value <= limit:
            found.append(
                Finding(
                    NOT_CONVERGED,
                    s,
                    f"the fit leaves its RMS residual at {_g(value)} {units[s]}, {value / noise[s]:.3g} times its "
                    f"noise ({_g(noise[s])} {units[s]}): the re-simulation does not follow the recording",
                )
            )
    return found


def identifiability(
    names: Sequence[str],
    fitted: Mapping[str, float],
    interval: Mapping[str, tuple[float, float]],
    bounds: Mapping[str, tuple[float, float]],
    correlation: np.ndarray,
    ends: Sequence[End],
    best_cost: float,
    dof: int,
    units: Mapping[str, str],
) -> list[Finding]:
    """The findings of parameters the signals do not tell (see the module docstring)."""
    found = []
    for name in names:
        low, high = interval[name]
        value, unit = fitted[name], units[name]
        lowest, highest = bounds[name]
        shown = f"[{_g(low)}, {_g(high)}] {unit}"
        if not math.isfinite(high - low):
            why = "the signals do not see it (its interval is infinite)"
        elif low < lowest:
            why = f"its interval {shown} reaches below {_g(lowest)} {unit}, the least it can be"
        elif high > highest:
            why = f"its interval {shown} reaches above {_g(highest)} {unit}, the most it can be"
        elif (high - low) / 2 > abs(value):
            why = f"its interval {shown} is wider than the value itself"
        else:
            continue
        found.append(Finding(NOT_IDENTIFIABLE, name, why))
    for i, a in enumerate(names):
        for j in range(i + 1, len(names)):
            if abs(correlation[i, j]) > CORRELATION_LIMIT:
                why = f"correlated with {names[j]} at {correlation[i, j]:.4f}: the signals tell only a combination"
                found.append(Finding(NOT_IDENTIFIABLE, a, why))
    if dof > 0 and best_cost > 0:
        variance = best_cost / dof
        limit = stats.chi2.ppf(0.95, len(names))
        for end in ends:
            if (end.cost - best_cost) / variance > limit:
                continue
            for name in names:
                low, high = interval[name]
                if not low <= end.end[name] <= high:
                    why = (
                        f"a start at {_g(end.start[name])} ended as well at {_g(end.end[name])} {units[name]}, "
                        f"outside the interval [{_g(low)}, {_g(high)}] of the best fit"
                    )
                    found.append(Finding(NOT_IDENTIFIABLE, name, why))
                    break
    return found
