"""The physical drive as an FMI 2.0 co-simulation unit (FMU), built with pythonfmu.

:mod:`interface` names what the FMU shows (inputs, outputs, parameters, with their units);
:mod:`units` turns the model's unit strings into FMI unit definitions; :mod:`slave` is the
co-simulation slave the FMU runs; :mod:`export` writes the ``.fmu`` file
(``boom-sim fmu``). What the FMU needs at run time: docs/fmu.md.
"""
