"""Where a report comes from: the software, when, which data file (with its SHA-256), which
capture run, which robot model and parameters."""

from __future__ import annotations

import datetime as dt
import html
from dataclasses import asdict, dataclass
from pathlib import Path

from calibration.data.dataset import Dataset
from calibration.version import software_version


def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    from calibration.files import sha256_file

    return sha256_file(path)


@dataclass
class Provenance:
    """What a report was made from.

    Attributes
    ----------
    software : ``cellcal X.Y.Z``
    created : when (UTC, ISO 8601, seconds)
    model : the robot model's name
    data_file, data_sha256 : the measurement file and the SHA-256 of its bytes
    run_id : the capture run (the CSV's ``# run:`` metadata), None when not recorded
    params_file, params_sha256 : the given parameters, when the current model came from a file
    """

    software: str
    created: str
    model: str
    data_file: str | None = None
    data_sha256: str | None = None
    run_id: str | None = None
    params_file: str | None = None
    params_sha256: str | None = None

    @classmethod
    def of(cls, model: str, data_file: str | Path | None = None, data: Dataset | None = None,
           params_file: str | Path | None = None, created: dt.datetime | None = None
           ) -> Provenance:
        """Provenance of a report on ``data_file`` (read for its hash), whose parsed
        :class:`Dataset` ``data`` carries the run id in its metadata."""
        created = created or dt.datetime.now(dt.UTC)
        run = (data.meta.get("run") or None) if data is not None else None
        return cls(
            software=software_version(),
            created=created.astimezone(dt.UTC).isoformat(timespec="seconds"),
            model=model,
            data_file=None if data_file is None else str(data_file),
            data_sha256=None if data_file is None else sha256_of(data_file),
            run_id=run,
            params_file=None if params_file is None else str(params_file),
            params_sha256=None if params_file is None else sha256_of(params_file),
        )

    def to_json(self) -> dict:
        return asdict(self)

    def html(self) -> str:
        """A definition list (``<dl id="provenance">``)."""
        rows = [("software", self.software), ("created", self.created),
                ("robot model", self.model)]
        if self.data_file:
            rows.append(("data file", self.data_file))
            rows.append(("data SHA-256", self.data_sha256))
        rows.append(("capture run", self.run_id or "not recorded in the data file"))
        if self.params_file:
            rows.append(("parameters", self.params_file))
            rows.append(("parameters SHA-256", self.params_sha256))
        items = "".join(
            f"<dt>{html.escape(k)}</dt><dd>"
            + (f'<code class="hash">{html.escape(v)}</code>' if "SHA" in k else html.escape(v))
            + "</dd>" for k, v in rows)
        return f'<dl class="prov" id="provenance">{items}</dl>'
