"""Analysis of saved runs: learning curves in, transfer metrics, intervals, tables and figures out.

    curves    read run directories and foreign logs (SB3, TensorBoard, CSVLogger) as :class:`Curve`
    metrics   transfer metrics and multi-seed statistics on arrays (Taylor & Stone 2009; Agarwal et al. 2021)
    report    ``drltg report``: both run sets checked, aligned, scored and compared
    plot      the report's figures
    tables    text, Markdown and CSV tables

Only numpy, scipy, pandas and matplotlib are used: nothing here imports torch, the method registry or the
task registry, so a report on saved runs starts fast and works where no learner can be built.
"""


def report_from_curves(frames, baseline, transfer, *, paired: bool = True, **settings) -> dict:
    """:func:`drltg.analysis.report.report_from_curves`: the ``transfer_metrics.json`` dict of curves in
    memory (``frames``: one per evaluation; ``baseline``, ``transfer``: seeds x evaluations)."""
    from drltg.analysis.report import report_from_curves as from_arrays

    return from_arrays(frames, baseline, transfer, paired=paired, **settings)
