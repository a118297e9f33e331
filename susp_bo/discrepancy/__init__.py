"""Model-discrepancy workflow: detect, name the missing effect, add it, recalibrate."""

from __future__ import annotations
