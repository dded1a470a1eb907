"""Time-domain simulation: scenario schema, environment, closed loop, compiled
rollout, metrics and outputs."""
