"""The three browser engines, as the browser tests use them: the drivers are shared with the client benchmark
(``tests/browsers.py``); a test needing an engine this machine lacks skips, and under CI=true fails."""

from __future__ import annotations

from browsers import DRIVERS, ENGINES, XVFB, Display, FirefoxDriver, missing
from support import lacking

__all__ = ["DRIVERS", "ENGINES", "XVFB", "Display", "FirefoxDriver", "require"]


def require(engine: str) -> None:
    """Skip (under CI=true: fail) unless ``engine`` can run here, naming what to install."""
    reason = missing(engine)
    if reason:
        lacking(f"{engine}: {reason}")
