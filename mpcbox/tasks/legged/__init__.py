"""Balance of any legged robot: feet by name, a reference from the actuator model, measures."""
