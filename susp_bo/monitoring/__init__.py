"""Monitoring: campaigns over dates, acceptable domains, P(outside), maintenance alarms.

- :mod:`~susp_bo.monitoring.campaigns` — campaign discovery (vehicle, date, line).
- :mod:`~susp_bo.monitoring.alarms` — P(outside), the alarm rule, the maintenance table.
- :mod:`~susp_bo.monitoring.runner` — :func:`monitor`: every campaign calibrated (resumable),
  ``monitor.json``.
- :mod:`~susp_bo.monitoring.campaign_results` — a campaign's results folder checked before
  it is reused (same runs, rig and output error; readable result and draws).
- :mod:`~susp_bo.monitoring.figures` — trend figures.
- :mod:`~susp_bo.monitoring.scenario` — a known-answer degradation scenario.
"""

from __future__ import annotations
