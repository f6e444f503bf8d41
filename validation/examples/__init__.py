"""Examples: a sweep spec (``sweep-phi-zeta.toml``) and the Python API in one page
(:mod:`validation.examples.api_example`, run by the test suite)."""
