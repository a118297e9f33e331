"""The four steps of the paper: design, kriging of log L, EGO refinement, MCMC."""

from __future__ import annotations
