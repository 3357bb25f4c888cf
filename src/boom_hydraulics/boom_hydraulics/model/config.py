"""Reading parameter files in the ROS 2 params YAML format, shared by the node and the CLI.

A file looks like::

    /**:
      ros__parameters:
        mode: physical
        piston_diameter_m: 0.04

``/**`` matches the node under any name and namespace (the shipped files use it);
``boom_sim`` or ``/boom_sim`` are accepted too. Nested mappings under
``ros__parameters`` are flattened with dots, as ROS 2 does.

Reading is lenient (``1e-06`` is a number, as rcl reads it); writing (:func:`dumps`,
:func:`default_file`) is strict: every float has a dot and a signed exponent where it has
one (``1.0e-06``, ``16000000.0``), the form YAML 1.1 reads as a float too. The ROS tools'
Python side (``ros2 param load``, rclpy's ``parameter_dict_from_yaml_file``, launch) reads
params files with PyYAML, which is YAML 1.1: there ``1e-06`` and ``16.0e6`` are strings.

A key given twice in one mapping is refused (YAML says keys are unique; PyYAML would take
the last without a word), as is a file over :data:`MAX_FILE_BYTES` or nested deeper than
Python can follow.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError
from .parameters import UNSOLVED, Parameters, as_dict, check_value, describe, from_mapping

NODE_NAME = "boom_sim"

#: The largest params file read, bytes: the shipped ones are a few KiB; PyYAML reads about
#: 0.1 MB/s into much memory, so a file of tens of MB would take minutes and gigabytes.
MAX_FILE_BYTES = 1 << 20


class _Loader(yaml.SafeLoader):
    """YAML loader that types numbers as ROS 2 does: ``1e-06`` and ``16.0e6`` are floats.

    PyYAML follows YAML 1.1, where a float needs a dot and a signed exponent; ROS 2's
    parameter parser reads any unquoted number. Without this, the node and the CLI
    would read the same file differently. A key twice in one mapping is an error.
    """

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, yaml.Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *anchor': merged keys may be given again
                continue
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, (str, int, float, bool)):
                continue
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    f"in the mapping at line {node.start_mark.line + 1}",
                    node.start_mark,
                    f"key {key!r} is given twice (lines {seen[key].start_mark.line + 1} and "
                    f"{key_node.start_mark.line + 1}); keep one",
                    key_node.start_mark,
                )
            seen[key] = key_node
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)(?:[eE][-+]?[0-9]+)?$|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$"
    ),
    list("-+0123456789."),
)


def load_yaml(text: str) -> Any:
    """Parse YAML text with ROS 2 number typing (see :class:`_Loader`); a yaml.YAMLError also
    for text nested deeper than Python's recursion can follow."""
    try:
        return yaml.load(text, Loader=_Loader)
    except RecursionError:
        raise yaml.YAMLError("it is nested deeper than can be read; a params file nests a few levels") from None


def flatten(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{'a': {'b': 1}}`` -> ``{'a.b': 1}``, as ROS 2 names nested parameters."""
    flat: dict[str, Any] = {}
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, prefix=f"{name}."))
        else:
            flat[name] = value
    return flat


def parameters_section(document: Any, source: str, node_name: str = NODE_NAME) -> dict[str, Any]:
    """The flattened ``ros__parameters`` of ``node_name`` (or ``/**``) in a parsed YAML document."""
    if not isinstance(document, Mapping):
        raise ConfigError(f"{source}: expected a mapping '{node_name}: ros__parameters: {{...}}' at top level")
    for name in (node_name, f"/{node_name}", "/**"):
        section = document.get(name)
        if section is None:
            continue
        if not isinstance(section, Mapping) or "ros__parameters" not in section:
            raise ConfigError(f"{source}: '{name}' must contain a 'ros__parameters' mapping")
        params = section["ros__parameters"]
        if not isinstance(params, Mapping):
            raise ConfigError(f"{source}: '{name}.ros__parameters' must be a mapping")
        return flatten(params)
    raise ConfigError(f"{source}: no section for node '{node_name}' (or '/**'); found {', '.join(map(str, document))}")


def read_document(path: str | Path) -> Any:
    """A params YAML file parsed with ROS 2 number typing; ConfigError names a missing or
    unreadable file, or where its YAML is malformed."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
        if len(data) <= MAX_FILE_BYTES:  # (a longer one is refused below, whatever its bytes)
            text = data.decode("utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read ({exc})") from None
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(
            f"{path}: is larger than a params file may be ({MAX_FILE_BYTES >> 20} MiB); name the params YAML "
            "(the shipped ones are a few KiB)"
        )
    try:
        document = load_yaml(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"{path}: malformed YAML{where}: {problem}") from None
    return document


def read_values(path: str | Path) -> dict[str, Any]:
    """The raw parameter values of a params YAML file, not yet validated."""
    return parameters_section(read_document(path), str(path))


def from_overrides(overrides: Mapping[str, Any], given_by: str = "on the command line") -> Parameters:
    """Validated parameters from the defaults with ``overrides``, an error naming where it lies
    as :func:`load`'s does."""
    _check_each(overrides, given_by)
    try:
        return from_mapping(overrides)
    except ConfigError as exc:
        raise ConfigError(f"{', '.join(overrides)} {given_by}: {exc}") from None


def _check_each(overrides: Mapping[str, Any], given_by: str) -> None:
    """ConfigError naming the first override that is wrong on its own (its type, choices, range)."""
    for key, value in overrides.items():
        try:
            check_value(key, value)
        except ConfigError as exc:
            raise ConfigError(f"{key} {given_by}: {exc}") from None


def load(
    path: str | Path, overrides: Mapping[str, Any] | None = None, given_by: str = "on the command line"
) -> Parameters:
    """Validated parameters from a params YAML file, with optional overrides on top. An error
    names where it lies: an override on its own (``bulk_modulus_pa on the command line``),
    the file, or the file with the overrides (a combination across parameters)."""
    values = read_values(path)
    _check_each(overrides or {}, given_by)
    values.update(overrides or {})
    try:
        return from_mapping(values)
    except ConfigError as exc:
        where = f"{path} with {', '.join(overrides)} {given_by}" if overrides else str(path)
        raise ConfigError(f"{where}: {exc}") from None


def scalar_text(value: Any) -> str:
    """``value`` (bool, int, float, str or a list of them) as YAML that rcl and YAML 1.1 both
    read back as the same value and type: ``1e-06`` -> ``1.0e-06``, ``'true'`` -> ``'true'`` quoted."""
    text = yaml.safe_dump(value, default_flow_style=True, width=1 << 30, allow_unicode=True)
    return text.removesuffix("\n").removesuffix("\n...").strip()


def dumps(values: Mapping[str, Any], node_name: str = "/**", comments: Mapping[str, str] | None = None) -> str:
    """A params YAML document of ``values`` for ``node_name`` (``/**``: any node), each value in
    the form every ROS 2 reader types alike (see :func:`scalar_text`), with an optional comment each."""
    lines = [f"{scalar_text(node_name)}:", "  ros__parameters:"]
    for name, value in values.items():
        comment = (comments or {}).get(name)
        lines.append(f"    {name}: {scalar_text(value)}" + (f"  # {comment}" if comment else ""))
    return "\n".join(lines) + "\n"


DEFAULT_FILE_HEADER = """\
# Physical mode (the default): the paper's crane geometry and masses with realistic oil,
# valve, supply and cylinder components. Every parameter is listed with its default;
# units are in the names (SI; pressures absolute). Load with:
#   boom-sim run --config config/default.yaml --duration 5 --out run.csv
#   ros2 run boom_hydraulics boom_sim --ros-args --params-file config/default.yaml
"""


def default_file() -> str:
    """The text of the shipped ``config/default.yaml``: every parameter the solvers read
    (not parameters.UNSOLVED) with its default and its description as a comment. A test
    keeps the shipped file equal to it."""
    values = {name: value for name, value in as_dict(Parameters()).items() if name not in UNSOLVED}
    comments = {}
    for name in values:
        meta = describe(name)
        comments[name] = meta["description"] + (f" [{meta['unit']}]" if meta["unit"] else "")
    return DEFAULT_FILE_HEADER + dumps(values, comments=comments)


def parse_assignment(text: str) -> tuple[str, Any]:
    """``'piston_diameter_m=0.063'`` -> ``('piston_diameter_m', 0.063)``, value read as YAML."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set expects key=value, got {text!r}")
    try:
        value = load_yaml(raw)
    except yaml.YAMLError:
        raise ConfigError(f"--set {key}: cannot read value {raw!r}") from None
    return key.strip(), value
