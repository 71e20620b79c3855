"""Campaigns: many simulated tows over scenarios, seeds, parameter values and estimators, run on Dask.

``lost campaign SPEC.toml --out DIR [--scheduler ADDRESS] [--workers N]``; the file's layout is in
:mod:`lost.host.campaign.spec`, the engine and its folder in :mod:`lost.host.campaign.engine`, one run in
:mod:`lost.host.campaign.run`.
"""

from .engine import CAMPAIGN_MARKER, read_rows, run_campaign
from .run import run_task, scenario_with
from .spec import CampaignSpec, RunTask, load_campaign

__all__ = ["CampaignSpec", "RunTask", "load_campaign", "run_campaign", "read_rows", "run_task", "scenario_with", "CAMPAIGN_MARKER"]
