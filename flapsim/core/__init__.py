"""The shared ground floor: MuJoCo glue (the one passive-callback dispatcher, wrenches, PD,
stepping, state, loading), errors, atomic io, interrupts, the software environment, parallel
workers, bundled assets and command-line validation. Imports nothing above it."""
