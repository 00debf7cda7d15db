"""Running a plan: the step loop (execution), the couplings, the backends, the subsystem
handles they drive and the causal transfer between them."""
