"""The command line: parser, commands, and the supervision of a run (signals, faults, locks)."""
