"""Jobs: one module per technique, each with its job (snapshot -> kernels -> write-back) and its
record (jobs/record.py); operators, the panel, the command line, `compare` and `demo` read the
records (jobs/techniques.py). Uses `bpy`; no user interface."""
