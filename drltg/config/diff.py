"""Comparing two configs (what changed between a saved run and a resumed one) and printing them."""
from __future__ import annotations

from pydantic import BaseModel

from drltg.config.env_options import task_env
from drltg.config.overrides import ENV_EXECUTION_KEYS, flatten
from drltg.config.run import RunConfig, absent_values, defaults, fields, option_owners
from drltg.config.sections import ALGO_SECTIONS
from drltg.config.values import expected, lookup
from drltg.errors import UsageError


def config_changes(saved: dict | RunConfig, cfg: dict | RunConfig, *, env_defaults: bool = True) -> list[str]:
    """The keys in which two configs of one task differ (``cfg`` gives the task). A key one of them
    lacks counts only when the other sets it to something else than its default, for ``env.*`` the
    task's: runs saved before the key existed, or before env settings were saved in full, stay the
    same run (resumable, and comparable in one report). Options of a transfer method that neither
    config uses do not count (a baseline is the same run whatever another method's defaults are), nor
    does a learner section one of them does not read (``soc.*`` of a SAC run: ``algo`` already says
    the runs differ, :data:`ALGO_SECTIONS`), nor ``transfer.source_checkpoint`` where neither has a
    source, nor ``ENV_EXECUTION_KEYS``.

    ``env_defaults=False`` leaves the task registry (and torch with it) unimported: an ``env.*`` key
    only one config sets is then not compared, its default being unknown (:func:`env_keys_set_once`
    names them)."""
    saved, cfg = (c.model_dump() if isinstance(c, BaseModel) else c for c in (saved, cfg))
    env = {}
    if env_defaults:
        try:
            env = task_env(cfg["task"])
        except (KeyError, UsageError, ValueError):  # a task this process does not know: no env defaults to fill in
            pass
    base = {**defaults(), "env": env}
    owners = option_owners()
    methods = {part for c in (saved, cfg) if isinstance(m := lookup(c, "transfer.method"), str)
               for part in m.split("+")}
    unknown = set() if env_defaults else set(env_keys_set_once(saved, cfg))
    if not env_defaults and (lookup(saved, "env") is KeyError) != (lookup(cfg, "env") is KeyError):
        unknown.add("env")

    absent = absent_values()

    def missing_as_default(a, b, key):  # a config saved before the key existed ran with its absent value
        return lookup(a, key) is KeyError and lookup(b, key) == absent.get(key, lookup(base, key))

    sourceless = all(lookup(c, "transfer.source") in (None, KeyError) for c in (saved, cfg))
    every = {s for sections in ALGO_SECTIONS.values() for s in sections}
    unread = {s for c in (saved, cfg) for s in every - set(ALGO_SECTIONS.get(lookup(c, "algo"), every))}

    def unused(key):  # an option of a method neither run uses changes nothing they do, nor does the
        if key == "transfer.source_checkpoint":  # checkpoint of a source neither of them reads
            return sourceless
        if key.split(".")[0] in unread:
            return True
        owner = owners.get(key.removeprefix("transfer.")) if key.startswith("transfer.") else None
        return owner is not None and owner not in methods

    return sorted(key for key in _diff_keys(saved, cfg)
                  if not (missing_as_default(saved, cfg, key) or missing_as_default(cfg, saved, key) or unused(key)
                          or key in ENV_EXECUTION_KEYS or key in unknown))


def env_keys_set_once(a: dict, b: dict) -> list[str]:
    """The ``env.*`` keys exactly one of two configs sets (one saved before env settings were saved in full)."""
    ea, eb = (c.get("env") if isinstance(c.get("env"), dict) else {} for c in (a, b))
    return sorted(f"env.{k}" for k in set(ea) ^ set(eb))


def _diff_keys(a, b, prefix=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in set(a) | set(b):
            yield from _diff_keys(a.get(k, KeyError), b.get(k, KeyError), f"{prefix}{k}.")
    elif a != b:
        yield prefix.rstrip(".")


def describe() -> str:
    """Every config key with its default, accepted values and meaning, as a Markdown table."""
    flat = flatten(defaults())
    rows = ["| key | default | accepted values | meaning |", "|---|---|---|---|"]
    for key, info in fields().items():
        default = _yaml().safe_dump(flat[key], default_flow_style=True).strip().removesuffix("...").strip()
        rows.append(f"| `{key}` | {default} | {expected(info)} | {info.description or ''} |")
    return "\n".join(rows)


def dump(cfg: RunConfig | dict) -> str:
    """``cfg`` as the YAML of ``config.yaml``: its sections in order, plain values."""
    return _yaml().safe_dump(cfg.model_dump() if isinstance(cfg, BaseModel) else cfg, sort_keys=False)


def _yaml():
    import yaml  # only when a config is printed or written: a refused key is answered without it

    return yaml
