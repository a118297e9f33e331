"""Measured runs on disk and synthetic measurements generated from a rig."""

from __future__ import annotations
