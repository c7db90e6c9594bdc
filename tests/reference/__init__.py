"""Reference implementations the tests check the product against (never shipped).

The package keeps only the forms the product runs (docs/architecture.md, "Three forms");
the slow, obviously correct implementations and the whole-log forms that exist only to
check the fast ones live here.
"""
