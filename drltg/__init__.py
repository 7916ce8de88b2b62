"""drltg — the DRL Transfer Gym: transfer-learning methods for deep RL as composable TorchRL parts.

Where each part is (every name below is also importable from ``drltg`` itself, e.g.
``from drltg import make_env, PotentialShaping``; ``import drltg`` imports no torch, a name is imported
when first used)::

    drltg.envs         make_env, get_task, get_pair, register_task, register_pair,
                       FourRoomsEnv, GridFourRoomsEnv                    tasks (FourRoomsEnv() is fourrooms/northeast)
                       register_gym_task                                 any Gymnasium env as a task
    drltg.gymnasium_ids  task_id, pair_ids: every task as the Gymnasium env drltg/<task>-v0
    drltg.transforms   PotentialShaping, TimeDependentPotential, SourceValue      reward and value shaping
    drltg.collectors   PolicyReuse, PiReuse, JumpStart, PRQL                     policy reuse, jump-start
                       collect_demonstrations, demonstration_buffer, mixed_batches   demonstrations
    drltg.losses       SoftOptionCriticLoss, behaviour_cloning, option_labels
    drltg.modules      load_weights (model reuse onto any module), option_transforms, make_option_policy
    drltg.config       resolve: a full, checked, typed run config (``cfg.optim.lr``; task defaults, ``KEY=VALUE``)
    drltg.learners     make_agent(env, cfg): actor, exploration policy, loss, target updater, optimiser;
                       UpdateStep: one gradient step of any learner; sample_batches(buffer, n)
    drltg.transfer     load_actor, load_critic, load_agent, load_from_run: a trained run as a source;
                       the named methods of ``drltg train -o transfer.method=...``
    drltg.training.loop        train(cfg, run_dir): the loop that writes a run directory (is_complete(run_dir));
                               evaluate(env, actor): success rate and return of deterministic episodes
    drltg.training.seeds       train_seeds(cfg, run_dir, n): n seeds in one process, one directory each
    drltg.training.seed_group  SeedGroup: N seeds' agents stacked, one vmapped update for all of them
    drltg.training.reevaluate  evaluate_run(run_dir, checkpoint="best"): a saved policy on fresh episodes
    drltg.experiments.experiment  experiment(pair, method, frames=, out=): source, baseline and transfer runs
                       over seeds, then the report (``drltg experiment``)
    drltg.experiments.sweep  sweep(spec, out): a grid of experiments from a YAML spec or mapping (``drltg sweep``)
    drltg.analysis     transfer metrics, reports, plots and tables from run directories (no torch)
    drltg.bench        bench_run(method), bench_report(): a method on the benchmark's tier, and the leaderboard
    drltg.cli          the ``drltg`` command

The examples in ``examples/`` compose these parts by hand, one transfer method each.
"""
import importlib

__version__ = "0.1.0"

_SURFACE = {
    "drltg.envs": ["make_env", "get_task", "get_pair", "register_task", "register_pair", "FourRoomsEnv",
                   "GridFourRoomsEnv", "register_gym_task"],
    "drltg.transforms": ["PotentialShaping", "TimeDependentPotential", "SourceValue"],
    "drltg.collectors": ["PolicyReuse", "PiReuse", "JumpStart", "PRQL", "collect_demonstrations",
                         "demonstration_buffer", "mixed_batches"],
    "drltg.losses": ["SoftOptionCriticLoss", "behaviour_cloning", "option_labels"],
    "drltg.modules": ["load_weights", "option_transforms", "make_option_policy"],
    "drltg.config": ["resolve"],
    "drltg.learners": ["make_agent", "UpdateStep", "sample_batches"],
    "drltg.transfer": ["load_actor", "load_critic", "load_agent", "load_from_run"],
    "drltg.training.loop": ["train", "evaluate", "is_complete"],
    "drltg.training.seeds": ["train_seeds"],
    "drltg.training.seed_group": ["SeedGroup"],
    "drltg.training.reevaluate": ["evaluate_run"],
    "drltg.experiments.experiment": ["experiment"],
    "drltg.experiments.sweep": ["sweep"],
    "drltg.bench": ["bench_run", "bench_report"],
}
_WHERE = {name: module for module, names in _SURFACE.items() for name in names}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'drltg' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_WHERE])


from drltg import gymnasium_ids  # noqa: E402

gymnasium_ids.register_ids()  # drltg/<task>-v0 for every task, as a Gymnasium 1.x package registers its ids
