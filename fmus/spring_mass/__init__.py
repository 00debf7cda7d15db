"""Spring-mass chain: :mod:`.core` (physics), :mod:`.slave` (the FMI model class) and
:mod:`.spring_mass_fmu` (the FMU's pythonfmu script, which imports it)."""
