"""The software's version, as recorded with runs, calibrations and reports."""

from __future__ import annotations


def software_version() -> str:
    """``cellcal X.Y.Z`` of the installed distribution (or of pyproject.toml in a checkout);
    ``cellcal (unknown version)`` when neither says. Imports nothing heavy."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        try:
            return f"cellcal {version('cellcal')}"
        except PackageNotFoundError:
            pass
        import tomllib
        from pathlib import Path

        pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
        return f"cellcal {tomllib.loads(pyproject.read_text())['project']['version']}"
    except Exception:  # noqa: BLE001 - a version is informative, never fatal
        return "cellcal (unknown version)"
