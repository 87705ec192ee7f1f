"""The participant's editor in a real browser. A package, so that its modules are ``browser.*``: no module here can
shadow one in tests/."""
