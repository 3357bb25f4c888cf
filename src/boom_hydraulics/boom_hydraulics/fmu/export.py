"""Writing the ``.fmu`` file: the drive's compiled code and the FMI wrapper, linked into one
shared library that needs no Python.

numba compiles the model's own code into an object file (:mod:`.native`); the machine's C
compiler (``cc``, or ``$CC``) compiles the FMI 2.0 wrapper written once in C
(native/fmi2_slave.c) with a header of this export's variables and parameters, and links
both into ``binaries/linux64/boom_drive.so``. The FMU holds that library, the model
description and, in its resources, the parameters it was exported with as YAML, for a
person to read. The file is written whole or not at all: built in a temporary folder,
zipped under a temporary name beside ``out``, then renamed.
"""

from __future__ import annotations

import os
import platform
import re
import shlex
import shutil
import string
import subprocess
import tempfile
import zipfile
from pathlib import Path

from ..errors import ConfigError
from ..files import atomic_path
from ..model import config
from ..model import physical as model
from ..model.parameters import PLANT_FAULTS, STROKE_LIMITS, Parameters, as_dict, describe
from ..solve import integrators
from ..solve.batch import stability_limit
from ..solve.outcomes import MAX_SUBSTEPS, VOLUME_ADVICE
from ..solve.stepping import HALVED_MOST
from . import native
from .interface import (
    EXTERNAL_FORCE,
    EXTERNAL_FORCE_PARAMETER,
    FIXED,
    MODEL_IDENTIFIER,
    PARAMETERS_FILE,
    VALVE_COMMAND,
    VARIABLES,
    unsupported,
)
from .model_description import guid_of, model_description

#: The FMI wrapper, written once in C.
WRAPPER = Path(__file__).with_name("native") / "fmi2_slave.c"
#: How far, as a fraction of the time step, a step size may be off a whole number of time
#: steps (a host that takes differences of its communication points rounds them).
GRID_TOLERANCE = 1e-6
#: The most time steps one communication step may take (t = n dt stays exact in a float).
MAX_STEPS_AT_ONCE = 2**53
#: Only the FMI functions leave the library: the model's compiled symbols stay inside.
VERSION_SCRIPT = "{ global: fmi2*; local: *; };\n"


class CompilerMissingError(ConfigError):
    """No C compiler to build the FMU's binary with."""


def compiler() -> list[str]:
    """The C compiler command: ``$CC`` where set, else ``cc``; CompilerMissingError where there is none."""
    command = shlex.split(os.environ.get("CC", "cc"))
    if not command or shutil.which(command[0]) is None:
        raise CompilerMissingError(
            f"no C compiler ({command[0] if command else '$CC'!s} not found): boom-sim fmu compiles the FMU's "
            "binary; install one (apt-get install gcc) or name it in CC"
        )
    return command


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _c_double(value: float) -> str:
    if value != value:  # NaN
        return "NAN"
    if value in (float("inf"), float("-inf")):
        return "INFINITY" if value > 0 else "-INFINITY"
    return repr(float(value))


def fault_pieces(template: str) -> list[str]:
    """``template`` (a line of parameters.PLANT_FAULTS) as C initializers of Piece: each its
    literal text, then the value it names (a row entry ``p.<name>``, or one of STROKE_LIMITS)
    with the printf format of its format spec (NULL: as Python writes a float, or the string);
    ValueError for a spec the FMU does not write as Python does."""
    pieces = []
    for text, field, spec, conversion in string.Formatter().parse(template):
        if field is None:
            pieces.append(f"{{{_c_string(text)}, SOURCE_NONE, 0, NULL}}")
            continue
        if conversion is not None or not re.fullmatch(r"(\.\d+g)?", spec or ""):
            raise ValueError(f"{template!r}: the FMU writes a value as Python does, or in a .<n>g spec only")
        if field.startswith("p."):
            source, index = "SOURCE_ROW", native.ROW.index(field[2:])
            spec = spec or (".0f" if native.kind_of(field[2:]) == "int" else "")  # an int as Python writes it
        else:
            source, index = "SOURCE_LIMIT", STROKE_LIMITS.index(field)
        pieces.append(f"{{{_c_string(text)}, {source}, {index}, {_c_string('%' + spec) if spec else 'NULL'}}}")
    return pieces


def header(params: Parameters, guid: str) -> str:
    """The C header of an FMU exported with ``params``: its GUID, the model's sizes, the
    operations of the compiled entry point, the row of exported parameters with each entry's
    range, the lines of the plant's faults (parameters.py's, as pieces) and its variables by
    value reference."""
    row = native.row_of(params)
    names = native.ROW
    lines = [
        "/* Written by boom-sim fmu (fmu/export.py) for one export; see fmi2_slave.c. */",
        f"#define MODEL_GUID {_c_string(guid)}",
        f"#define N_ROW {len(names)}",
        f"#define N_STATE {native.N_STATE}",
        f"#define N_CONSTANTS {native.N_CONSTANTS}",
        f"#define N_OUTPUTS {native.N_OUTPUTS}",
        f"#define N_VARIABLES {len(VARIABLES)}",
        f"#define ENERGY_INDEX {model.ENERGY_STATES[0]}",
        f"#define STABILITY_LIMIT {_c_double(stability_limit(params))}",
        f"#define MAX_SUBSTEPS {MAX_SUBSTEPS}",
        f"#define GRID_TOLERANCE {_c_double(GRID_TOLERANCE)}",
        f"#define MAX_STEPS_AT_ONCE {_c_double(float(MAX_STEPS_AT_ONCE))}",
        f'#define MAX_STEPS_TEXT "{MAX_STEPS_AT_ONCE}"',
        f"#define N_LIMITS {len(STROKE_LIMITS)}",
        f"#define CONSTANT_A {model.Constants._fields.index('a')}",
        f"#define CONSTANT_B {model.Constants._fields.index('b')}",
        f"#define ROW_TIME_STEP {names.index('time_step_s')}",
        f"#define ROW_SUBSTEPS {names.index('substeps')}",
        f"#define HALVING {1 if integrators.METHODS[params.method].halving else 0}",
        f"#define HALVED_MOST {HALVED_MOST}",
        *(f"#define ROW_{name} {k}" for k, name in enumerate(names)),
        f"enum {{ {', '.join(f'OP_{name} = {code}' for name, code in native.OPERATIONS.items())} }};",
        "enum { KIND_REAL, KIND_INTEGER, KIND_STRING };",
        "enum { ROLE_VALVE, ROLE_ROW, ROLE_OUTPUT, ROLE_CALCULATED };",
        "typedef struct { int kind; int role; int index; const char *name; } Variable;",
        "typedef struct {",
        "    int n_choices; const char *const *choices; const char *choice_list; int is_int;",
        "    int has_low; double low; int low_inclusive; int has_high; double high;",
        "    const char *low_text; const char *high_text; const char *unit; const char *description;",
        "} RowCheck;",
        f"static const double EXPORTED_ROW[N_ROW] = {{{', '.join(_c_double(v) for v in row)}}};",
        f"static const char *const ROW_NAMES[N_ROW] = {{{', '.join(_c_string(n) for n in names)}}};",
        f"static const int ROW_FIXED[N_ROW] = {{{', '.join('1' if n in FIXED else '0' for n in names)}}};",
        f"static const char *const VOLUME_ADVICE[] = {{{', '.join(_c_string(a) for a in VOLUME_ADVICE)}}};",
    ]
    checks = []
    for k, name in enumerate(names):
        meta = describe(name)
        choices = tuple(meta["choices"] or ())
        if choices:
            lines.append(f"static const char *const CHOICES_{k}[] = {{{', '.join(_c_string(c) for c in choices)}}};")
        low, high = meta["low"], meta["high"]
        checks.append(
            "{"
            + ", ".join(
                (
                    str(len(choices)),
                    f"CHOICES_{k}" if choices else "NULL",
                    _c_string(", ".join(choices)),
                    "1" if meta["type"] == "int" else "0",
                    "1" if low is not None else "0",
                    _c_double(low if low is not None else 0.0),
                    "1" if meta["low_inclusive"] else "0",
                    "1" if high is not None else "0",
                    _c_double(high if high is not None else 0.0),
                    _c_string(repr(low)),
                    _c_string(repr(high)),
                    _c_string(f" {meta['unit']}" if meta["unit"] else ""),  # as parameters.py writes a value
                    _c_string(meta["description"]),
                )
            )
            + "}"
        )
    lines.append(f"static const RowCheck ROW_CHECKS[N_ROW] = {{{', '.join(checks)}}};")
    lines.append("enum { SOURCE_NONE, SOURCE_ROW, SOURCE_LIMIT };")
    lines.append("typedef struct { const char *text; int source; int index; const char *format; } Piece;")
    counts = []
    for k, template in enumerate(PLANT_FAULTS, start=1):
        pieces = fault_pieces(template)
        lines.append(f"static const Piece FAULT_{k}[] = {{{', '.join(pieces)}}};")
        counts.append(str(len(pieces)))
    lines.append(f"#define N_PLANT_FAULTS {len(PLANT_FAULTS)}")
    faults = ", ".join(f"FAULT_{k}" for k in range(1, len(PLANT_FAULTS) + 1))
    lines.append(f"static const Piece *const PLANT_FAULTS[N_PLANT_FAULTS] = {{{faults}}};")
    lines.append(f"static const int PLANT_FAULT_PIECES[N_PLANT_FAULTS] = {{{', '.join(counts)}}};")
    variables = []
    for variable in VARIABLES:
        kind = {"float": "KIND_REAL", "int": "KIND_INTEGER", "str": "KIND_STRING"}[variable.kind]
        if variable.name == VALVE_COMMAND:
            role, index = "ROLE_VALVE", 0
        elif variable.causality == "output":
            role, index = "ROLE_OUTPUT", native.OUTPUT_NAMES.index(variable.name)
        else:
            role = "ROLE_CALCULATED" if variable.causality == "calculatedParameter" else "ROLE_ROW"
            index = names.index(EXTERNAL_FORCE_PARAMETER if variable.name == EXTERNAL_FORCE else variable.name)
        variables.append(f"{{{kind}, {role}, {index}, {_c_string(variable.name)}}}")
    lines.append(f"static const Variable VARIABLES[N_VARIABLES] = {{{', '.join(variables)}}};")
    return "\n".join(lines) + "\n"


def build_binary(params: Parameters, guid: str, folder: Path) -> Path:
    """``folder``/boom_drive.so: the drive's compiled code and the FMI wrapper for ``params``."""
    command = compiler()
    code, symbol = native.object_code(params.method)
    (folder / "boom_native.o").write_bytes(code)
    (folder / "boom_drive_model.h").write_text(
        header(params, guid) + f'#define BOOM_NATIVE_SYMBOL "{symbol}"\n', encoding="utf-8"
    )
    (folder / "exports.map").write_text(VERSION_SCRIPT, encoding="ascii")
    binary = folder / f"{MODEL_IDENTIFIER}.so"
    args = [
        *command, "-std=c11", "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-I", str(folder),
        "-o", str(binary), str(WRAPPER), str(folder / "boom_native.o"),
        "-Wl,-z,notext", "-Wl,--no-undefined", f"-Wl,--version-script={folder / 'exports.map'}", "-lm",
    ]  # fmt: skip
    result = subprocess.run(args, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        said = (result.stderr or result.stdout).strip().splitlines()
        raise ConfigError(f"{command[0]} could not build the FMU's binary: {said[-1] if said else result.returncode}")
    return binary


def write_fmu(params: Parameters, out: Path) -> None:
    """An FMI 2.0 co-simulation FMU of the physical drive with ``params`` as its parameters'
    start values, written to ``out`` (a ``.fmu`` file); ConfigError for parameters the FMU
    cannot run, an output name without the ``.fmu`` ending or no C compiler (CompilerMissingError)."""
    out = Path(out)
    reason = unsupported(params)
    if reason is not None:
        raise ConfigError(reason)
    if out.suffix != ".fmu":
        raise ConfigError(f"--out {out}: an FMU is a .fmu file; name one, e.g. boom_drive.fmu")
    if platform.system() != "Linux" or platform.machine() not in ("x86_64", "AMD64"):
        raise ConfigError(f"boom-sim fmu builds linux64 binaries, on Linux x86-64 only (this is {platform.platform()})")
    compiler()
    description = model_description(params)
    with tempfile.TemporaryDirectory(prefix="boom-fmu-") as work, atomic_path(out, suffix=".fmu") as tmp:
        binary = build_binary(params, guid_of(description), Path(work))
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", description)
            archive.write(binary, f"binaries/linux64/{MODEL_IDENTIFIER}.so")
            archive.writestr(f"resources/{PARAMETERS_FILE}", config.dumps(as_dict(params)))
