"""The module an exported FMU loads (its ``resources/boom_drive_fmu.py``): the slave class of
the installed boom_hydraulics, which pythonfmu's binary finds by its base class, Fmi2Slave.

pythonfmu's binary (findClass, 0.7.0) runs this file once more on every fmi2Instantiate,
with this module's namespace as its globals, and then releases that namespace once more
than it holds it (a Py_DECREF of the borrowed PyModule_GetDict). The namespace was freed
under the live module and the host process aborted at exit ("corrupted double-linked
list", 4 of 8 runs of a lift-hold-lower cycle). Each run of this file therefore holds one
more reference to its namespace, which the release takes back.
"""

from boom_hydraulics.fmu.slave import BoomDrive

globals().setdefault("_held_namespaces", []).append(globals())

__all__ = ["BoomDrive"]
