"""Physics only: tire, wheel, chassis, load transfer, kinematics. Pure functions, no estimation."""
