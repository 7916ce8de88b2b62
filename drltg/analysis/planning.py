r"""How many pairs a study needs, planned from a pilot: an honest estimate, not a replay of the sample.

Replaying the pilot's differences (as if further seeds scored exactly like these) overstates what more
seeds give: the pilot's spread is itself a noisy, often low, estimate. :func:`pairs_for_power` plans a
paired t test (whose power is close to the exact sign-flip test's for normal differences,
``results/verdicts``) for the pilot's mean difference :math:`\hat\delta` and a spread at its one-sided
``spread_confidence`` upper confidence limit, :math:`s\sqrt{(n-1)/\chi^2_{1-c,\,n-1}}` (Browne 1995's
conservative plan): the smallest :math:`N` with

.. math:: P(|T_{N-1}(\hat\delta\sqrt N/s_u)| > t_{1-\alpha/2,\,N-1}) \ge \text{power},

:math:`T` noncentral t, and at least the fewest pairs at which the sign-flip test can reach :math:`\alpha`
at all (:math:`2/2^N < \alpha`).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np


def paired_t_power(effect: float, n: int, level: float = 0.05) -> float:
    """Power of the two-sided paired t test at ``level`` with ``n`` pairs for a standardised effect
    (mean difference over the differences' sd)."""
    from scipy import stats

    df, nc = n - 1, effect * math.sqrt(n)
    crit = stats.t.ppf(1 - level / 2, df)
    return float(stats.nct.sf(crit, df, nc) + stats.nct.cdf(-crit, df, nc))


def pairs_for_power(differences: Sequence[float], power: float = 0.8, level: float = 0.05,
                    spread_confidence: float = 0.8, most: int = 1000) -> int | None:
    """Pairs for ``power`` at two-sided ``level``, planned from the pilot's paired ``differences`` (module
    docstring); ``None`` below 3 pairs, where their mean is 0, or where more than ``most`` would be needed."""
    from scipy import stats

    d = np.asarray(differences, float)
    n = d.size
    if n < 3 or d.mean() == 0:
        return None
    sd = d.std(ddof=1)
    if sd == 0:
        upper = 0.0
    else:
        upper = sd * math.sqrt((n - 1) / stats.chi2.ppf(1 - spread_confidence, n - 1))
    fewest = next(k for k in range(2, most + 1) if 2 / 2 ** k < level)
    if upper == 0:
        return fewest
    effect = abs(d.mean()) / upper
    for k in range(max(fewest, 3), most + 1):
        if paired_t_power(effect, k, level) >= power:
            return k
    return None
