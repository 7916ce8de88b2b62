"""Transfer metrics and their statistics as pure functions over arrays and plain records, as rliable's are:
nothing here reads a run directory or looks up a task; the caller (:mod:`drltg.report`, :mod:`drltg.bench`)
passes return ranges and task facts in as data.

    metrics       transfer metrics and multi-seed statistics on arrays (Taylor & Stone 2009; Agarwal et al. 2021)
    stats         intervals and randomization tests over per-seed scores
    aggregate     rliable's aggregates over tasks (IQM, P(T > B), profiles)
    claims        the sentences a verdict is stated in, generated from the numbers
    sequential    the ``--seeds auto`` plan of looks; operating: its level and power
    plot, tables  figures and tables of the numbers

Only numpy, scipy, pandas, rliable and matplotlib are used: nothing here imports torch, the method registry or
the task registry, so a report on saved runs starts fast and works where no learner can be built.
"""
