"""Implementations of the command-line commands, one module per command."""

from __future__ import annotations
