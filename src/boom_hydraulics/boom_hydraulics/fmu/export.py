"""Writing the ``.fmu`` file: pythonfmu's builder with the drive's slave and its parameters.

The FMU holds the slave's entry module (boom_drive_fmu.py), the parameters it was exported
with (a params YAML), the names of its variables, pythonfmu's Python files and its binaries,
and the model description. It runs the drive of the boom_hydraulics installed in the
Python that loads it (docs/fmu.md). The file is written whole or not at all: built under
a temporary name beside ``out``, then renamed.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from ..errors import ConfigError
from ..files import atomic_path
from ..model import config
from ..model.parameters import Parameters, as_dict
from .interface import PARAMETERS_FILE, VARIABLES, VARIABLES_FILE, unsupported

#: The module the FMU loads, a file of this package copied into the FMU's resources.
ENTRY = Path(__file__).with_name("boom_drive_fmu.py")


def write_fmu(params: Parameters, out: Path) -> None:
    """An FMI 2.0 co-simulation FMU of the physical drive with ``params`` as its parameters'
    start values, written to ``out`` (a ``.fmu`` file); ConfigError for parameters the FMU
    cannot run or an output name without the ``.fmu`` ending."""
    out = Path(out)
    reason = unsupported(params)
    if reason is not None:
        raise ConfigError(reason)
    if out.suffix != ".fmu":
        raise ConfigError(f"--out {out}: an FMU is a .fmu file; name one, e.g. boom_drive.fmu")
    from pythonfmu import FmuBuilder

    with tempfile.TemporaryDirectory(prefix="boom-fmu-") as work, atomic_path(out, suffix=".fmu") as tmp:
        folder = Path(work)
        script = folder / ENTRY.name
        shutil.copyfile(ENTRY, script)
        parameters, variables = folder / PARAMETERS_FILE, folder / VARIABLES_FILE
        parameters.write_text(config.dumps(as_dict(params)), encoding="utf-8")
        variables.write_text("".join(f"{variable.name}\n" for variable in VARIABLES), encoding="utf-8")
        try:
            FmuBuilder.build_FMU(script, dest=tmp, project_files=[parameters, variables])
        finally:  # the builder imports the entry module from its folder: leave no trace of it
            while str(folder) in sys.path:
                sys.path.remove(str(folder))
            sys.modules.pop(script.stem, None)
