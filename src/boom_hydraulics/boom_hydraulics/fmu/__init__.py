"""The physical drive as an FMI 2.0 co-simulation unit (FMU) that needs no Python on its host.

:mod:`interface` names what the FMU shows (inputs, outputs, parameters, with their units);
:mod:`units` turns the model's unit strings into FMI unit definitions and display units;
:mod:`model_description` writes the model description; :mod:`native` compiles the model's
own functions as written (its step, outputs, parameter derivations and the plant's checks)
into an object file; :mod:`export` links it with the FMI wrapper (native/fmi2_slave.c) and writes the ``.fmu`` file
(``boom-sim fmu``). What the FMU needs at run time: docs/fmu.md.
"""
