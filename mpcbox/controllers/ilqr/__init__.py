"""Control-limited iLQR (offline and receding-horizon)."""
