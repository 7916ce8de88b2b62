"""The generated regions of the docs and results, one module per study; ``results/claims.py`` writes them."""
