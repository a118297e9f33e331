"""Posterior figures for a railway engineer: Fig. 1, Fig. 2 and the pair plot.

The public entry points are in :mod:`susp_bo.plots` (``posterior_figures`` and the
``plot_*`` functions); this package holds one module per figure and what they share.
"""
