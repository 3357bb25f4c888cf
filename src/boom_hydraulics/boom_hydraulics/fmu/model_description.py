"""The FMU's modelDescription.xml: its variables (interface.py) with their units, display
units, ranges and the exported parameters as start values.

Value references run over every variable in the order of :data:`interface.VARIABLES`
(inputs, outputs, parameters), whatever its type; the binary reads them in the same order
(the header export.py writes).
"""

from __future__ import annotations

import hashlib
from typing import Any
from xml.etree.ElementTree import Element, SubElement, indent, tostring

from .. import __version__
from ..model.parameters import Parameters
from .interface import EXTERNAL_FORCE, EXTERNAL_FORCE_PARAMETER, MODEL_IDENTIFIER, VARIABLES, Variable
from .units import base_exponents, base_factor, display_units, unit_name

DESCRIPTION = (
    "Hydraulic drive that lifts a crane boom (physical mode): 4/3 proportional valve, supply, "
    "two-chamber cylinder, seal friction, end stops and the boom's Lagrange dynamics"
)
#: The log categories the binary logs under.
LOG_CATEGORIES = (
    ("logStatusDiscard", "a step the drive cannot take, and why"),
    ("logStatusError", "a call refused for what was set, and why"),
)


def start_of(variable: Variable, params: Parameters) -> Any:
    """The start value of ``variable`` in an FMU exported with ``params`` (None: an output)."""
    if variable.causality in ("output", "calculatedParameter"):
        return None
    if variable.name == "valve_command":
        return 0.0
    name = EXTERNAL_FORCE_PARAMETER if variable.name == EXTERNAL_FORCE else variable.name
    return getattr(params, name)


def _text(value: Any, kind: str) -> str:
    if kind == "str":
        return str(value)
    return repr(int(value)) if kind == "int" else repr(float(value))


def _units(root: Element) -> None:
    units = SubElement(root, "UnitDefinitions")
    defined = {unit_name(v.unit): v.unit for v in VARIABLES if v.kind == "float"}
    for name, unit in sorted(defined.items()):
        node = SubElement(units, "Unit", name=name)
        exponents, factor = base_exponents(unit), base_factor(unit)
        attributes = {base: str(n) for base, n in exponents.items()}
        if factor != 1.0:
            attributes["factor"] = repr(factor)
        if attributes:
            SubElement(node, "BaseUnit", attributes)
        for display, scale in display_units(unit):
            SubElement(node, "DisplayUnit", name=display, factor=repr(scale))


def _variable(parent: Element, reference: int, variable: Variable, params: Parameters) -> None:
    attributes = {
        "name": variable.name,
        "valueReference": str(reference),
        "description": variable.description,
        "causality": variable.causality,
        "variability": variable.variability if "arameter" in variable.causality else "continuous",
    }
    if variable.causality == "parameter":
        attributes["initial"] = "exact"
    if variable.causality == "calculatedParameter":
        attributes["initial"] = "calculated"
    if variable.kind == "str":
        attributes["variability"] = variable.variability
    node = SubElement(parent, "ScalarVariable", attributes)
    tag = {"float": "Real", "int": "Integer", "str": "String"}[variable.kind]
    value: dict[str, str] = {}
    if variable.kind == "float":
        value["unit"] = unit_name(variable.unit)
        shown = display_units(variable.unit)
        if shown:
            value["displayUnit"] = shown[0][0]
    if variable.kind != "str":
        for attribute, bound in (("min", variable.low), ("max", variable.high)):
            if bound is not None:
                value[attribute] = _text(bound, variable.kind)
    start = start_of(variable, params)
    if start is not None:
        value["start"] = _text(start, variable.kind)
    SubElement(node, tag, value)


def model_description(params: Parameters) -> bytes:
    """The modelDescription.xml of the FMU exported with ``params``; its GUID is a hash of the rest."""
    root = Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": MODEL_IDENTIFIER,
            "guid": "GUID",
            "description": DESCRIPTION,
            "author": "boom_hydraulics maintainers",
            "license": "Apache-2.0",
            "generationTool": f"boom_hydraulics {__version__} (boom-sim fmu)",
            "variableNamingConvention": "flat",
            "numberOfEventIndicators": "0",
        },
    )
    SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": MODEL_IDENTIFIER,
            "canHandleVariableCommunicationStepSize": "true",
            "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canNotUseMemoryManagementFunctions": "true",
            "canGetAndSetFMUstate": "false",
            "canSerializeFMUstate": "false",
            "providesDirectionalDerivative": "false",
        },
    )
    _units(root)
    categories = SubElement(root, "LogCategories")
    for name, meaning in LOG_CATEGORIES:
        SubElement(categories, "Category", name=name, description=meaning)
    SubElement(root, "DefaultExperiment", startTime="0.0", stepSize=repr(params.time_step_s))
    variables = SubElement(root, "ModelVariables")
    for reference, variable in enumerate(VARIABLES):
        _variable(variables, reference, variable, params)
    structure = SubElement(root, "ModelStructure")
    outputs = SubElement(structure, "Outputs")
    initial = SubElement(structure, "InitialUnknowns")
    for index, variable in enumerate(VARIABLES, start=1):
        if variable.causality == "output":
            SubElement(outputs, "Unknown", index=str(index))
    for index, variable in enumerate(VARIABLES, start=1):
        if variable.causality in ("output", "calculatedParameter"):  # in the order of their indices
            SubElement(initial, "Unknown", index=str(index))
    indent(root)
    text = tostring(root, encoding="unicode")
    guid = "{" + hashlib.sha256(text.encode()).hexdigest()[:32] + "}"
    guid = f"{{{guid[1:9]}-{guid[9:13]}-{guid[13:17]}-{guid[17:21]}-{guid[21:33]}}}"
    root.set("guid", guid)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="unicode").encode() + b"\n"


def guid_of(description: bytes) -> str:
    """The GUID written in a model description."""
    from xml.etree.ElementTree import fromstring

    return fromstring(description).attrib["guid"]
