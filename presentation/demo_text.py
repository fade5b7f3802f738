"""The demo's closing table (``cellcal demo``): the validation RMS stage by stage against
the noise floor, and what became of the hidden effect."""

from __future__ import annotations


def before_after(r) -> str:
    """The closing table of a demo result (``rms`` by stage label, ``noise_floor_mm``,
    ``hidden``, ``found``, ``seconds``, ``files``)."""
    labels = list(r.rms)
    width = max(len(s) for s in labels)
    lines = [f"{'model':<{width}}  RMS on the validation poses"]
    for label in labels:
        lines.append(f"{label:<{width}}  {r.rms[label]:8.4f} mm  "
                     f"({r.rms[label] / r.noise_floor_mm:5.2f} x noise floor)")
    lines.append(f"{'noise floor':<{width}}  {r.noise_floor_mm:8.4f} mm  (sqrt(3) x tracker sigma)")
    verdict = ("found it" if r.found == r.hidden else
               f"the diagnosis proposed {r.found or 'nothing'}")
    lines.append(f"hidden effect: {r.hidden} -> {verdict}; {r.seconds:.0f} s in all; "
                 f"open {r.files.get('report', 'report.html')}")
    return "\n".join(lines)
