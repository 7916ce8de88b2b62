"""Many runs: an experiment (source, baseline and transfer runs over seeds), a sweep of experiments, and
the executor that trains their runs on a local process pool or Ray."""
