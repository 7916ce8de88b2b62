r"""``drltg report``: did the transfer method help? Metrics, a plot and tables from learning curves.

    drltg report --baseline RUNS... --transfer RUNS... [--threshold 150 | --threshold 80%] [--out DIR]
    drltg report --matrix DIR [--metric mean_return_gain] [--out DIR]

The report is one pipeline (:func:`transfer_report`, :func:`compute`):

1. read: both sides with :func:`drltg.report.curves.read_curves` (run directories, directories of seed runs,
   globs, SB3 / TensorBoard / CSVLogger logs);
2. check (:func:`check_runs`): no run twice, one task, one configuration a side, paired or not;
3. align (:func:`align`): every curve is compared on the target task over a common interval
   ``[start, budget]``: ``start`` is the latest first evaluation of any run (frame 0 for drltg runs),
   ``budget`` the shortest run's last evaluation unless ``--budget`` sets it; nothing is invented past a
   run's last evaluation;
4. score (:func:`score_runs`): the per-seed scores, one row per run (``result["scores"]``, a DataFrame
   with ``side`` and ``pair`` columns);
5. metrics (:func:`metric_values`): each entry of ``METRICS`` turns score columns into a metric and its
   interval, so a new metric is one entry there; ``TABLE_ROWS`` places it in the table;
6. write (:func:`render`): JSON, CSV (through :mod:`drltg.analysis.tables`) and the plot.

The per-seed scores are aggregated (B = baseline, T = transfer, A = area, span = budget - start, L = the
mean of each side's seeds, which for pairs equals the mean of ``d_i = T_i - B_i``; ``*_iqm``: L = the
interquartile mean of each side; formulas in :mod:`drltg.analysis.metrics`, intervals and tests in
:mod:`drltg.analysis.stats`):

``mean_return_gain``          L(A_T / span) - L(A_B / span): return gained per frame on average over the
                              budget; unchanged when a constant is added to every reward (the headline)
``jumpstart``                 L(mean of the first K evaluations of T) - L(same of B)
``asymptotic_performance``    L(mean of T's evaluations in [budget - FRAC span, budget]) - same of B; a
                              final performance, not an asymptote, unless the equivalence test (TOST)
                              shows each side's mean curve changes by less than ``--convergence-margin``
                              x its range over the last ``--trend-window``
``transfer_ratio``            (L(A_T) - L(A_B)) / |L(A_B)|; changes when a constant is added to rewards;
                              null when |L(A_B)| <= 0.01 x span x max |y|
``time_to_threshold_<side>``  per run: the first evaluation from which it stays >= threshold until the
                              budget, over at least 2 later evaluations (``--sustain K``: for K >= 2
                              evaluations; ``--crossing first``: the first evaluation >= threshold);
                              per side: the upper median over seeds, a frame a run had, by which a strict
                              majority of seeds has crossed; null = no majority
``final_trend_<side>``        change of the mean curve over the last ``--trend-window`` (least squares)
``probability_of_improvement`` P(T > B): paired, the fraction of pairs with T_i > B_i; unpaired, over all
                              (B seed, T seed) combinations; ties 1/2; on the areas (``_initial``,
                              ``_final``: on the initial / final performances)
``*_with_source``             total time (Taylor & Stone 2009, sec. 3.1): a transfer run has first spent
                              S source frames (``transfer.source``'s config or ``--source-frames``), so
                              both sides are compared at equal total frames: mean return over
                              [start + S, budget] of B against T's first span - S target frames; the
                              transfer's time to threshold + S
``<name>_ci``                 ``--confidence`` interval: paired t or Welch/Hsu t for mean differences,
                              Fieller for the ratio, Clopper-Pearson (pairs) or Newcombe (unpaired) for
                              P(T > B); inside the quantity's range (a rate's difference within [-1, 1]);
                              absent (with the reason in ``settings.warnings``) below 3 seeds a side,
                              without spread, or for a ratio whose denominator's interval contains 0
``<name>_p_value``            two-sided p-value of no effect, from the test behind the interval (t test;
                              sign test or exact permutation test for P(T > B)); the exact permutation
                              test's where the per-seed scores are skewed or bimodal (``settings.p_values``)
``<name>_p_adjusted``         Holm's adjustment over the report's family: every metric with a p-value
                              (``settings.family`` names them)
``<name>_p_exact``            (mean differences) the exact permutation test of no effect, valid at any
                              number of seeds and any shape of scores

Pairing: drltg runs are paired when every baseline seed (``config.yaml``) has exactly one transfer run
with the same seed; ``--paired`` pairs foreign logs in the order given. ``settings.pairing`` says which
and why. A side must hold one configuration (``--allow-mixed`` to override) and no run twice.

Outputs (written through temporary files and ``os.replace``, and only once every input is read and
checked): ``transfer_metrics.json`` (``metrics``, ``settings`` with every choice and warning,
``per_seed``), ``transfer_metrics.csv`` (``metric,value,ci_low,ci_high,p_value,p_adjusted``),
``transfer_plot.png`` and ``.svg`` (or the format ``--figure-format`` names; ``--figure one-column``: a PDF one
column wide, :mod:`drltg.analysis.figure_style`); ``--matrix`` writes ``transfer_matrix.{png,svg,csv,json}``. All
options: :class:`ReportSettings`.
"""
from drltg.report.catalogue import COMPARISONS, METRICS, TABLE_ROWS, Metric, table_rows
from drltg.report.describe import BETTING_CLAIM, COVERAGE_CLAIM, COVERAGE_EXCEPTIONS
from drltg.report.matrix import check_metric, find_matrix_cells, transfer_matrix
from drltg.report.outputs import format_table, metrics_rows, render
from drltg.report.pipeline import compute, read_runs, report_from_curves, transfer_report
from drltg.report.settings import SETTINGS_DEFAULTS, ReportSettings, parse_frames, parse_threshold

__all__ = [
    "transfer_report", "report_from_curves", "compute", "read_runs", "render", "format_table", "metrics_rows",
    "ReportSettings", "SETTINGS_DEFAULTS", "parse_threshold", "parse_frames",
    "Metric", "METRICS", "TABLE_ROWS", "COMPARISONS", "table_rows",
    "BETTING_CLAIM", "COVERAGE_CLAIM", "COVERAGE_EXCEPTIONS", "transfer_matrix", "find_matrix_cells", "check_metric",
]
