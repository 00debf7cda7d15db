"""Spring-mass chain: :mod:`.core` (physics) and :mod:`.spring_mass_fmu` (FMI wrapper)."""
