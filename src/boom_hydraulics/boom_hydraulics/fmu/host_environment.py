"""The environment a host that is no Python needs to run the FMU with this Python.

    eval "$(tools/with-env python -m boom_hydraulics.fmu.host_environment)"

prints ``export`` lines for a POSIX shell: ``LD_PRELOAD`` (this Python's shared libpython,
whose symbols the FMU's Linux binary uses), ``PYTHONHOME`` (where its standard library is)
and ``PYTHONPATH`` (this ``sys.path``: the package and what it imports). Status 1 with one
line where this Python has no shared libpython (docs/fmu.md).
"""

from __future__ import annotations

import os
import shlex
import sys
import sysconfig

from ..errors import BoomHydraulicsError
from ..programs import run_main


def environment(paths: list[str]) -> dict[str, str]:
    """The variables a host that is no Python needs to start this Python for the FMU, with
    ``paths`` (this ``sys.path``, say) as its module search path."""
    name, folder = sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LIBDIR")
    library = os.path.join(folder or "", name or "")
    if not sysconfig.get_config_var("Py_ENABLE_SHARED") or not os.path.isfile(library):
        raise BoomHydraulicsError(
            f"{sys.executable} has no shared libpython for a host to preload; "
            "use a Python built with --enable-shared (a distribution's python3 is)"
        )
    return {
        "LD_PRELOAD": library,
        "PYTHONHOME": sys.base_prefix,
        "PYTHONPATH": os.pathsep.join(path for path in paths if path),
    }


def main() -> int:
    def body() -> int:
        variables = environment(sys.path[1:])  # sys.path[0]: the folder python -m was started in
        print("".join(f"export {key}={shlex.quote(value)}\n" for key, value in variables.items()), end="")
        return 0

    return run_main("host_environment", body)


if __name__ == "__main__":
    sys.exit(main())
