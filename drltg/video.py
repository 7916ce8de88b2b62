"""`drltg video SOURCE`: render episodes of a trained policy (a run directory) or of the scripted
demonstrator (``demonstrator``, manipulation tasks) to a video (mp4 or gif) and a PNG filmstrip.

    drltg video runs/lift-seed0                       # the run's task, its last checkpoint
    drltg video demonstrator --task lift-place-barrier --out videos --format gif

The policy acts deterministically. Frames come from the env's own ``render(td)``; robosuite tasks
render offscreen through MuJoCo, which needs a GL backend on a headless machine: ``MUJOCO_GL=egl``
(Mesa's libEGL; robosuite's default) or ``MUJOCO_GL=osmesa`` (Debian's libosmesa6).
"""
from __future__ import annotations

import argparse
import io
import os
from pathlib import Path

import numpy as np

from drltg.errors import UsageError
from drltg.store import rundir


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", help="a run directory (its last checkpoint) or 'demonstrator'")
    p.add_argument("--task", help="task to render (default: the run's task; required for the demonstrator)")
    p.add_argument("--episodes", type=int, default=1, help="episodes to render (default 1)")
    p.add_argument("--max-steps", type=int, help="stop an episode after this many steps (default: its end)")
    p.add_argument("--out", type=Path, help="output folder (default RUN_DIR/videos; required for the demonstrator)")
    p.add_argument("--format", choices=("mp4", "gif"), default="mp4", help="video format (default mp4)")
    p.add_argument("--fps", type=int, default=20, help="frames per second (default 20, real time at 20 Hz)")
    p.add_argument("--camera", default="frontview", help="robosuite camera (default frontview)")
    p.add_argument("--size", type=int, default=256, help="frame height and width in pixels, robosuite (default 256)")
    p.add_argument("--strip", type=int, default=8, help="frames in the filmstrip (default 8)")
    p.add_argument("--seed", type=int, default=0, help="environment seed (default 0)")


def _policy_and_env(args):
    """The acting policy, the env to step (with the agent's transforms), the env that renders, the
    policy's name and the task."""
    from drltg.envs import make_env

    if args.source == "demonstrator":
        if not args.task:
            raise UsageError("the demonstrator needs --task (lift, lift-place or lift-place-barrier).")
        from drltg.envs.robosuite import demonstrator_for

        try:
            policy = demonstrator_for(args.task)
        except ValueError:
            known = "lift, lift-place and lift-place-barrier"
            raise UsageError(f"the demonstrator solves {known}, not {args.task!r}.") from None
        env = make_env(args.task, seed=args.seed)
        return policy, env, env, "demonstrator", args.task

    run = Path(args.source).expanduser().resolve()
    config = run / rundir.CONFIG
    if not config.is_file():
        raise UsageError(f"'{run}' is not a run directory: it holds no {rundir.CONFIG}.")
    weights, _ = rundir.load_networks(run)
    from torchrl.envs import TransformedEnv

    from drltg import config as config_lib
    from drltg.learners import make_agent
    from drltg.store import networks
    from drltg.training.loop import build_env
    from drltg.transfer.source import check_same_spaces

    cfg = config_lib.updated(config_lib.build(config_lib.load_yaml(config), saved=True), {"device": "cpu"})
    task = args.task or cfg.task
    env_settings = cfg.env if task == cfg.task else {}  # another task: its own settings
    base = build_env(config_lib.updated(cfg, {"task": task, "env": env_settings}), seed=args.seed)
    if task != cfg.task:
        check_same_spaces(build_env(cfg), base, f"run '{run.name}' ({cfg.task})",
                          f"task '{task}'")
    agent = make_agent(base, cfg)
    reason = networks.mismatch(agent.loss.state_dict(), weights)
    if reason:
        raise UsageError(f"the networks of '{run}' do not fit the {cfg.algo} learner its {rundir.CONFIG} describes "
                         f"({reason}).")
    agent.loss.load_state_dict(weights)
    env = TransformedEnv(base)
    for transform in agent.env_transforms:
        env.append_transform(transform.clone())
    return agent.actor, env, base, run.name, task


def record(policy, env, render_env, max_steps: int | None = None) -> tuple[list[np.ndarray], list[bool]]:
    """One episode: the frames (the reset state, then one per step) and whether each state is a success."""
    import torch
    from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp

    td = env.reset()
    frames, success = [render_env.render(td)], [bool(td.get("success", torch.zeros(1)).any())]
    steps = 0
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        while max_steps is None or steps < max_steps:
            td = env.step(policy(td))
            steps += 1
            frames.append(render_env.render(td["next"]))
            success.append(bool(td["next"].get("success", torch.zeros(1)).any()))
            if td["next", "done"].any():
                break
            td = step_mdp(td)
    return frames, success


def write_video(path: Path, frames: list[np.ndarray], fps: int) -> None:
    import imageio.v2 as imageio

    # imageio picks the writer from the file's suffix: the temporary file gets the video's own
    with rundir.atomic_path(path) as tmp:
        video = f"{tmp}{path.suffix}"
        try:
            if path.suffix == ".gif":
                imageio.mimsave(video, frames, duration=1000 / fps, loop=0)
            else:
                imageio.mimsave(video, frames, fps=fps, macro_block_size=1)
            os.replace(video, tmp)
        finally:
            if os.path.exists(video):
                os.remove(video)


def write_filmstrip(path: Path, frames: list[np.ndarray], success: list[bool], count: int, title: str) -> None:
    """``count`` evenly spaced frames side by side, each labelled with its step; success in green."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    picks = np.unique(np.linspace(0, len(frames) - 1, max(1, count)).round().astype(int))
    fig, axes = plt.subplots(1, len(picks), figsize=(2.2 * len(picks), 2.6), squeeze=False)
    for ax, t in zip(axes[0], picks):
        ax.imshow(frames[t])
        ax.set_title(f"step {t}" + (" success" if success[t] else ""), fontsize=9,
                     color="green" if success[t] else "black")
        ax.set_xticks([]), ax.set_yticks([])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    rundir.atomic_write(path, buf.getvalue())


GL_LIBRARIES = {"egl": ("EGL", "Mesa's libEGL, Debian package libegl1"),
                "osmesa": ("OSMesa", "Debian package libosmesa6")}


def check_gl_backend() -> None:
    """Name a missing offscreen GL library in one sentence: without it MuJoCo fails at import time, deep
    inside TorchRL, for any env (``MUJOCO_GL`` is read when ``torchrl.envs`` is imported)."""
    import ctypes.util

    backend = os.environ.get("MUJOCO_GL")
    if backend in GL_LIBRARIES and ctypes.util.find_library(GL_LIBRARIES[backend][0]) is None:
        library, package = GL_LIBRARIES[backend]
        raise UsageError(f"MUJOCO_GL={backend} needs the {library} library, which is not installed ({package}).")


def run(args: argparse.Namespace) -> int:
    check_gl_backend()
    if args.episodes < 1 or args.strip < 1 or args.fps < 1 or args.size < 16:
        raise UsageError("--episodes, --strip and --fps must be positive and --size at least 16.")
    if args.max_steps is not None and args.max_steps < 1:
        raise UsageError(f"--max-steps must be at least 1 (the steps an episode may take), got {args.max_steps}.")
    if args.out is None and args.source == "demonstrator":
        raise UsageError("the demonstrator needs --out, the folder to write the videos to.")
    policy, env, render_env, name, task = _policy_and_env(args)
    if hasattr(render_env, "render_camera"):
        render_env.render_camera, render_env.render_size = args.camera, (args.size, args.size)
    out = rundir.check_directory(args.out or Path(args.source) / "videos", "--out")
    for episode in range(args.episodes):
        try:
            frames, success = record(policy, env, render_env, args.max_steps)
        except Exception as err:  # a missing GL backend surfaces here, deep inside MuJoCo
            if "GL" in str(err) or "EGL" in type(err).__name__ or "display" in str(err).lower():
                raise UsageError(
                    f"offscreen rendering failed ({err}); set MUJOCO_GL=egl (Mesa libEGL) or "
                    "MUJOCO_GL=osmesa (libosmesa6)."
                ) from None
            raise
        stem = f"{task.replace('/', '-')}-{name}-seed{args.seed}-ep{episode}"
        video, strip = out / f"{stem}.{args.format}", out / f"{stem}-filmstrip.png"
        write_video(video, frames, args.fps)
        outcome = f"success at step {success.index(True)}" if any(success) else "no success"
        write_filmstrip(strip, frames, success, args.strip, f"{task}, {name}, episode {episode}: {outcome}")
        print(f"{video}  ({len(frames) - 1} steps, {outcome})")
        print(strip)
    env.close()
    return 0
