"""``drltg bench report``: the leaderboard as files, ``leaderboard.{md,json}``, ``profile.png`` and each
pair's learning curves ``curves-<pair>.png``, written atomically into one folder."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drltg.bench.board import ALPHA, board_table, label, leaderboard, pair_table
from drltg.bench.run import tier_root
from drltg.bench.suite import LATEST, Tier, get_tier

__all__ = ["bench_report", "board_markdown"]


def _protocol(tier: Tier) -> list[str]:
    lines = []
    for g in tier.groups:
        s = g.spec
        every, episodes = s["overrides"].get("eval.every", "the task's"), s["overrides"].get("eval.episodes", 16)
        lines.append(f"- `{g.name}`: {', '.join(g.pairs)}; {s['algos'][0]}, {s['seeds']} paired seeds from seed "
                     f"{s['seed']}, sources {s['source_frames']:,} frames, targets {s['frames']:,} frames, evaluated "
                     f"every {every} frames on {episodes} episodes")
    return lines


def _against_none(verdict: str) -> str:
    return "undecided against no transfer" if verdict == "undecided" else f"{verdict} than no transfer"


def _best_sentence(board: dict) -> str:
    best = next((r for r in board["rows"] if r["method"] == board["best_reference"] and r["kind"] == "reference"),
                None)
    if best is None:
        return "No reference row covers every pair on protocol, so no row is compared with a best reference."
    a = best["aggregate"]
    lo, hi = a["ft_iqm"][1]
    return (f"The best reference row is {best['method']}: IQM of FT {a['ft_iqm'][0]:+.2f} [{lo:+.2f}, {hi:+.2f}] over "
            f"{len(a['pairs'])} pairs, {_against_none(a['against_none']['verdict'])} (p = "
            f"{a['against_none']['p']:.2g}, {a['against_none']['test']}).")


def board_markdown(board: dict, tier: Tier) -> str:
    left = [f"- {r['method']} on {pair}: {why}" for r in board["rows"] for pair, why in r["left_out"].items()]
    return "\n".join([
        f"# drltg bench {board['suite']}, tier `{board['tier']}`", "",
        f"{tier.summary}. Protocol:", *_protocol(tier), "",
        "Score of a pair: forward transfer FT = (AUC_T - AUC_B) / (1 - AUC_B) on the task's return normalised to "
        "[0, 1] by its declared range (AUC: the mean normalised return over the budget; AUC_B: no transfer's, "
        "over its seeds). Aggregates over the pairs: the IQM of every seed's FT and P(T > B) (rliable), with 95% "
        f"stratified-bootstrap intervals. Verdicts: exact sign-flip tests over paired seeds at {ALPHA} (stratified "
        "over pairs for the aggregates); higher, lower or undecided.", "",
        "## Ranking", "", _best_sentence(board), "", board_table(board),
        "A row that is not the protocol's (column 'off protocol') is shown, never ranked.", "",
        "## Per pair", "",
        "FT of each pair; ↑ higher than no transfer, ↓ lower, · undecided (exact sign-flip over paired seeds); "
        "n/a where the method cannot run.", "", pair_table(board),
        *(["## Left out", "", *left, ""] if left else []),
        "![performance profiles](profile.png)", ""])


def _pair_curves(board: dict, tier: Tier) -> dict[str, bytes]:
    """``curves-<pair>.png`` for every pair: each row's transfer runs and no transfer's, normalised."""
    from drltg.analysis.curves import read_eval_csv
    from drltg.analysis.plot import plot_method_curves

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
                    lines[label(r)] = found
            if lines:
                files[f"curves-{pair}.png"] = plot_method_curves(f"{pair} ({board['suite']} {board['tier']})",
                                                                 lines, baseline)[0]
    return files


def bench_report(*, out: str | Path | None = "runs/bench", reference: str | Path | None = None,
                 version: str = LATEST, tier: str = "quick", board_dir: str | Path | None = None,
                 reps: int = 2000) -> tuple[dict, Path]:
    """Write the leaderboard of ``tier`` (the reference's rows and ``out``'s) into ``board_dir`` (default
    ``<out>/<version>/<tier>/board``); returns the board and the folder."""
    from drltg.analysis.plot import plot_profiles
    from drltg.store import atomic

    the_tier = get_tier(version, tier)
    board = leaderboard(the_tier, version, out=out, reference=reference, reps=reps)
    folder = Path(board_dir) if board_dir else tier_root(out if out is not None else reference, version, tier) / "board"
    profiled = [{"algo": "sac", "method": label(r), "variant": "",
                 "normalised": True, **r["aggregate"]} for r in board["rows"] if r["aggregate"] and not r["marks"]]
    files = {"leaderboard.json": json.dumps(board, indent=1) + "\n",
             "leaderboard.md": board_markdown(board, the_tier),
             "ranking.md": _best_sentence(board) + "\n\n" + board_table(board), "pairs.md": pair_table(board),
             **_pair_curves(board, the_tier)}
    if profiled:
        files["profile.png"] = plot_profiles(profiled, over="the tier's pairs")[0]
    atomic.write_files(folder, files)
    return board, folder
