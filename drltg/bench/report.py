"""``drltg bench report``: the leaderboard as files, ``leaderboard.{md,json}``, ``profile.png`` and each
pair's learning curves ``curves-<pair>.png``, written atomically into one folder."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drltg.analysis.figure_style import DEFAULT, FigureStyle
from drltg.bench.board import ALPHA, baseline_sentence, board_table, label, leaderboard, p_text, pair_table
from drltg.bench.run import tier_root
from drltg.bench.suite import LATEST, Tier, get_tier

__all__ = ["bench_report", "board_markdown"]


def _protocol(tier: Tier) -> list[str]:
    lines = []
    for g in tier.groups:
        s = g.spec
        every, episodes = s["overrides"].get("eval.every", "the task's"), s["overrides"].get("eval.episodes", 16)
        if g.sources is None:
            sources = f"sources {s['source_frames']:,} frames"
        else:
            until = f" until a success rate of {g.sources.success:g}" if g.sources.success is not None else ""
            sources = f"the suite's sources (each trained{until}, at most {g.sources.frames:,} frames)"
        search = (f", the baseline tuned over {', '.join(g.baseline_search)}" if g.baseline_search else "")
        lines.append(f"- `{g.name}`: {', '.join(g.pairs)}; {s['algos'][0]}, {s['seeds']} paired seeds from seed "
                     f"{s['seed']}, {sources}, targets {s['frames']:,} frames, evaluated every {every} frames on "
                     f"{episodes} episodes{search}")
    return lines


def _against_none(verdict: str) -> str:
    return "undecided against no transfer" if verdict == "undecided" else f"{verdict} than no transfer"


def _best_sentence(board: dict) -> str:
    """The top row's verdict against no transfer, with its p-value and the pairs it was ranked on, and the row
    every other is compared with."""
    top = next((r for r in board["rows"] if r["rank"] == 1), None)
    if top is None:
        return "No row is on protocol, so no row is ranked or compared with a best reference."
    a, none = top["aggregate"], top["aggregate"]["against_none"]
    lo, hi = a["ft_iqm"][1]
    over = (f"{len(a['pairs'])} pairs" if len(a["pairs"]) == len(board["pairs"]) else
            f"the {len(a['pairs'])} of {len(board['pairs'])} pairs it covers")
    sentence = (f"The top row is {label(top)}: IQM of FT {a['ft_iqm'][0]:+.2f} [{lo:+.2f}, {hi:+.2f}] over {over}, "
                f"{_against_none(none['verdict'])} ({p_text(none['p'], none['draws'], none['p_floor'])}, "
                f"{none['test']}).")
    best = next((r for r in board["rows"] if r["method"] == board["best_reference"] and r["kind"] == "reference"
                 and r["rank"]), None)
    if best is top:
        return sentence + " It is the best reference row, the one every row on protocol is compared with."
    if best is None:
        return sentence + " No reference row is on protocol, so no row is compared with a best reference."
    b = best["aggregate"]
    return sentence + (f" The best reference row, the one every row on protocol is compared with, is "
                       f"{best['method']} (rank {best['rank']}, IQM of FT {b['ft_iqm'][0]:+.2f}).")


def _tests(board: dict) -> str:
    """How the board's printed p-values were found, from its own rows: exact where every sign pattern was
    counted, else Monte Carlo, whose value at its floor is a bound."""
    tests = [t for r in board["rows"] if r["aggregate"] for t in (r["aggregate"]["against_none"],
             r.get("against_best", {}), *r.get("against_best", {}).get("pairs", {}).values())]
    monte = sorted({(t["draws"], t["p_floor"]) for t in tests if t.get("draws") is not None})
    if not monte:
        return "Every p-value on the board is exact: every sign pattern counted"
    shown = "; ".join(f"{d:,} draws, floor {f:.2g}" for d, f in monte)
    return (f"A p-value is exact where every sign pattern is counted, else Monte Carlo "
            f"({shown}); one at its floor is a bound and written as one, {p_text(monte[0][1], *monte[0])}")


def _unverified(board: dict) -> list[str]:
    """The sentence naming the rows whose runs record no source digest, paired by seed on the folder alone."""
    rows = [f"{label(r)} ({len(r['unverified'])} of {len(r['pairs'])} pairs)" for r in board["rows"] if r["unverified"]]
    if not rows:
        return []
    return [f"Source not verified by digest: {', '.join(rows)}; their transfer runs were written before drltg "
            "recorded the digest of the source each run loaded, so their pairing by seed rests on the source "
            "folder's name alone.", ""]


def board_markdown(board: dict, tier: Tier) -> str:
    left = [f"- {r['method']} on {pair}: {why}" for r in board["rows"] for pair, why in r["left_out"].items()]
    return "\n".join([
        f"# drltg bench {board['suite']}, tier `{board['tier']}`", "",
        f"{tier.summary}. Protocol:", *_protocol(tier), "",
        "Score of a pair: forward transfer FT = (AUC_T - AUC_B) / (1 - AUC_B) on the task's return normalised to "
        "[0, 1] by its declared range (AUC: the mean normalised return over the budget; AUC_B: no transfer's, "
        "over its seeds). Aggregates over the pairs: the IQM of every seed's FT and P(T > B) (rliable), with 95% "
        f"stratified-bootstrap intervals. Verdicts at {ALPHA}: sign-flip tests over paired seeds (stratified over "
        f"pairs for the aggregates); higher, lower or undecided. {_tests(board)}.", "",
        "## Ranking", "", _best_sentence(board), "", baseline_sentence(board.get("baseline_tuning")), "",
        board_table(board),
        "Rows on protocol are ranked by the IQM of FT alone, each over the pairs it covers: a row that covers fewer "
        "('ranked on these') is ranked on those. The best reference row is the top-ranked reference row; the "
        "column against it compares each row on the pairs both cover. A row that is not the protocol's (column "
        "'off protocol') is shown, never ranked, and compared with no row but its own baseline.", "",
        *_unverified(board),
        "## Per pair", "",
        "FT of each pair; ↑ higher than no transfer, ↓ lower, · undecided: each pair's exact sign-flip test over "
        f"paired seeds, Holm-adjusted within the row (the family: that row's per-pair tests against no transfer, "
        f"at most {len(board['pairs'])}); n/a where the method cannot run.", "", pair_table(board),
        *(["## Left out", "", *left, ""] if left else []),
        "![performance profiles](profile.png)", ""])


def _pair_curves(board: dict, tier: Tier, figure: FigureStyle = DEFAULT) -> dict[str, bytes]:
    """``curves-<pair>.png`` for every pair: each row's transfer runs and no transfer's, normalised."""
    from drltg.analysis.plot import files as named
    from drltg.analysis.plot import plot_method_curves
    from drltg.report.curves import read_eval_csv

    def runs(folder: Path, lo: float, hi: float):
        curves = [read_eval_csv(p) for p in sorted(folder.glob("seed-*/eval.csv"))]
        if not curves:
            return None
        n = min(len(c) for c in curves)
        return curves[0].frames[:n], (np.stack([c.values[:n] for c in curves]) - lo) / (hi - lo)

    files = {}
    for group in tier.groups:
        for pair in group.pairs:
            lines, baseline = {}, None
            for r in board["rows"]:
                if pair not in r["pairs"]:
                    continue
                cell = Path(r["folder"]) / group.name / pair / group.spec["algos"][0]
                lo, hi = r["pairs"][pair]["value_range"]
                baseline = baseline or runs(cell / "baseline", lo, hi)
                found = runs(cell / r["method"] / "transfer", lo, hi)
                if found is not None:
                    lines[_figure_label(r)] = found
            if lines:
                files.update(named(f"curves-{pair}", plot_method_curves(
                    f"{pair} ({board['suite']} {board['tier']})", lines, baseline, style=figure)))
    return files


def _figure_label(r: dict) -> str:
    """A row's name on a figure: its table name, and "off protocol" where it is marked (drawn, never ranked)."""
    whose = ["yours"] * (r["kind"] == "yours") + ["off protocol"] * bool(r["marks"])
    return r["method"] + (f" ({', '.join(whose)})" if whose else "")


def bench_report(*, out: str | Path | None = "runs/bench", reference: str | Path | None = None,
                 version: str = LATEST, tier: str = "quick", board_dir: str | Path | None = None,
                 reps: int = 2000, figure: FigureStyle = DEFAULT) -> tuple[dict, Path]:
    """Write the leaderboard of ``tier`` (the reference's rows and ``out``'s) into ``board_dir`` (default
    ``<out>/<version>/<tier>/board``), its figures drawn as ``figure`` says; returns the board and the folder."""
    from drltg.analysis.plot import files as named
    from drltg.analysis.plot import plot_profiles
    from drltg.store import atomic

    the_tier = get_tier(version, tier)
    board = leaderboard(the_tier, version, out=out, reference=reference, reps=reps)
    folder = Path(board_dir) if board_dir else tier_root(out if out is not None else reference, version, tier) / "board"
    profiled = [{"algo": "sac", "method": _figure_label(r), "variant": "",
                 "normalised": True, **r["aggregate"]} for r in board["rows"] if r["aggregate"]]
    files = {"leaderboard.json": json.dumps(board, indent=1) + "\n",
             "leaderboard.md": board_markdown(board, the_tier),
             "ranking.md": "\n\n".join([_best_sentence(board), baseline_sentence(board.get("baseline_tuning")),
                                         board_table(board)]),
             "pairs.md": pair_table(board),
             **_pair_curves(board, the_tier, figure)}
    if profiled:
        files.update(named("profile", plot_profiles(profiled, over="the tier's pairs", style=figure)))
    atomic.write_files(folder, files)
    return board, folder
