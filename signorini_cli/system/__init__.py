"""The machine: atomic file writes, child processes, clocks and memory."""
