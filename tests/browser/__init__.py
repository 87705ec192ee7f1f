"""The participant's editor in a real browser. A package, so that its modules are ``browser.*``: its
conftest.py never stands in for tests/conftest.py (``from conftest import …`` always means that one), and no
module here can shadow one in tests/."""
