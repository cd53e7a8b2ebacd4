"""The workflow of scioc: data I/O and validation, the CLI, benchmarks and reports."""
