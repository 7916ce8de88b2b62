"""One training run: the loop (:mod:`~drltg.training.loop`), its evaluation, checks and seed groups; the
run directory it writes is :mod:`drltg.store`."""
