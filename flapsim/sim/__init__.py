"""MuJoCo glue shared by every system: loading, the passive-force dispatcher, PD, state."""
