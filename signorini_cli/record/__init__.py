"""The results on disk: rates.csv, study.h5 and status.txt written, and read back to resume."""
