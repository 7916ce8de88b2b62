"""A run directory on disk, below everything that trains, transfers or reports: its files and their atomic
writes, the manifest of their digests, data-only checkpoints and the owner lock (:mod:`~drltg.store.rundir`,
:mod:`~drltg.store.manifest`). Imports nothing above :mod:`drltg.errors` and :mod:`drltg.safe_yaml`."""
