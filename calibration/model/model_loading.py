"""Loading a robot model by name, by model YAML path or from a URDF's serial chain."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import ModelError
from ..files import read_text
from .robot_model import MAX_MODEL_BYTES, RobotModel, builtin_models, model_from_dict, parse_yaml
from .urdf_model import is_urdf_spec, load_urdf_model


def load_model(name_or_path: str | Path) -> RobotModel:
    """Load a built-in model by name (``"ur10e"``), a model YAML by path, or the serial chain
    of a URDF (``"robot.urdf#base_link:tool0"``, or ``"robot.urdf"`` when unambiguous)."""
    text_source = str(name_or_path)
    if is_urdf_spec(text_source):
        return load_urdf_model(text_source)
    path = Path(text_source)
    if path.suffix in (".yaml", ".yml") or path.exists() or "/" in text_source:
        text = read_text(path, ModelError, "model file", MAX_MODEL_BYTES)
    else:
        names = builtin_models()
        if text_source not in names:
            raise ModelError(
                f"unknown model {text_source!r}: built-in models are {', '.join(names)}; "
                "or give the path of a model YAML file"
            )
        folder = resources.files("calibration.model") / "builtin"
        text = (folder / f"{text_source}.yaml").read_text()
        text_source = f"built-in model {text_source}"
    return model_from_dict(parse_yaml(text, text_source, ModelError), text_source)
