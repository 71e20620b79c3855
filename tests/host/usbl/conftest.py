"""Shared pieces of the INS+USBL tests: a short, quick scenario."""

import numpy as np
import pytest

from lost.host.usbl.ins import ImuSamples
from lost.host.usbl.scenario import ReplyFaultSpec, TowSpec, UsblScenario


def short_scenario(**changes) -> UsblScenario:
    """Five minutes of straight tow at 600 m, with the shipped scenario's instruments."""
    settings = dict(name="short", seed=3, duration_s=300.0, tow=TowSpec(depth_m=600.0, layback_m=400.0, course=((300.0, 0.0),)),
                    faults=ReplyFaultSpec(dropout_rate=0.05, dropout_rate_turning=0.0, bad_fix_rate=0.05, bad_fix_rate_turning=0.0))
    settings.update(changes)
    return UsblScenario(**settings)


def imu_samples(table) -> ImuSamples:
    return ImuSamples(table.time_s.to_numpy(), table[["fx_m_s2", "fy_m_s2", "fz_m_s2"]].to_numpy(),
                      table[["wx_rad_s", "wy_rad_s", "wz_rad_s"]].to_numpy())


@pytest.fixture(name="short_scenario", scope="session")
def short_scenario_factory():
    """The factory of short scenarios (keyword changes over the defaults)."""
    return short_scenario


@pytest.fixture(name="imu_samples", scope="session")
def imu_samples_function():
    """Table to :class:`ImuSamples`."""
    return imu_samples


@pytest.fixture(scope="session")
def short_tow():
    from lost.host.usbl.simulate import simulate_tow

    return simulate_tow(short_scenario())


@pytest.fixture
def rng():
    return np.random.default_rng(7)
