"""pytest configuration for the Python reference tests: a report header saying what is tested
against what (binary path, Pinocchio version, where the example-robot-data URDFs are)."""

import os
from pathlib import Path


def pytest_report_header(config):
    repo = Path(__file__).resolve().parents[2]
    binary = os.environ.get("SPATIAL_DYNAMICS_BIN") or str(repo / "target" / "release" / "spatial_dynamics")
    lines = [f"spatial_dynamics binary: {binary}{'' if os.path.isfile(binary) else '  (MISSING)'}"]
    try:
        import pinocchio

        lines.append(f"pinocchio: {pinocchio.__version__} ({pinocchio.__file__})")
    except Exception as exc:  # the test module's import will fail loudly on its own
        lines.append(f"pinocchio: not importable ({exc})")
    try:
        from test_pinocchio_reference import robots_dir

        lines.append(f"example-robot-data: {robots_dir()}")
    except Exception as exc:
        lines.append(f"example-robot-data: not found ({exc})")
    return lines
