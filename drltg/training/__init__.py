"""One training run: the loop (:mod:`~drltg.training.loop`) and its run directory (:mod:`~drltg.training.rundir`)."""
