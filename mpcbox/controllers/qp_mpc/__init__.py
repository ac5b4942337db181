"""Linear MPC with explicit contact forces in friction cones, solved as a sparse QP."""
