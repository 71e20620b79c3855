import os

from hypothesis import HealthCheck, settings

# CI gets more examples than a developer's quick run; both are deterministic per example database.
settings.register_profile("dev", max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci" if os.environ.get("CI") else "dev")


def pytest_collection_modifyitems(config, items):
    """Tests under tests/sim run the generated Verilog on Verilator: marked ``verilator``, so ``make check`` can leave them out."""
    import pytest

    for item in items:
        if "tests/sim/" in item.path.as_posix():
            item.add_marker(pytest.mark.verilator)
