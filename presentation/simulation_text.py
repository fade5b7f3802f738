"""The line ``cellcal simulate`` prints about the measurement CSV it wrote."""

from __future__ import annotations

from calibration.data.dataset import Dataset
from calibration.fit.error_model import ErrorModel
from calibration.fit.simulate import BlunderTruth


def simulation_line(out: str, data: Dataset, error_model: ErrorModel, sigma_mm: float,
                    blunders: BlunderTruth | None = None) -> str:
    """``wrote sim.csv: 300 calibration + 300 validation poses of a simulated ur10e
    (geometric,base,tool hidden), tracker sigma 0.015 mm``."""
    n_valid = int(data.is_valid.sum())
    return (f"wrote {out}: {data.n - n_valid} calibration + {n_valid} validation poses of a "
            f"simulated {error_model.model.name} ({','.join(error_model.labels)} hidden), "
            f"tracker sigma {sigma_mm} mm"
            + (f"; {len(blunders.index)} blunders" if blunders is not None else ""))
