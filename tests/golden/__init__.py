"""Golden outputs of the CLI on the sample logs (made by make_golden.py, checked by
tests/test_golden.py)."""
