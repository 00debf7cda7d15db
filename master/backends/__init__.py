"""Where subsystems run: in this process, or on Ray workers (same interface)."""
