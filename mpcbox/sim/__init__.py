"""Closed-loop simulation: the loop, disturbances and the generic measures of a run."""
