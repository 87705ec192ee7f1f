"""The ways out of a Prolific study in Chromium: declining consent, and leaving from the editor, each end on a
page whose button takes the participant back to Prolific with that way's code."""

import pytest
from demostudy import make_app
from serverproc import StudyServer

from .pagehelp import ARGS, CHROMIUM, new_context, require_browser, screenshot, start

pytestmark = pytest.mark.slow
PROLIFIC = "https://app.prolific.com/submissions/complete?cc="


@pytest.fixture
def prolific_server(tmp_path, demo_resources):
    require_browser()
    text = demo_resources.read_text().replace('kind = "link"', 'kind = "prolific"')
    text = text.replace('target = "scenes/', f'target = "{demo_resources.parent}/scenes/')
    study = tmp_path / "prolific.toml"
    study.write_text(text)
    database = f"sqlite:///{tmp_path / 'study.sqlite3'}"
    make_app(tmp_path, database, studies=[study])
    with StudyServer(tmp_path / "instance", database, workers=1, migrate=False, study=study) as server:
        yield server.base


def entry(n: int) -> str:
    """Prolific's entry parameters for participant ``n``."""
    return f"PROLIFIC_PID={n:024x}&SESSION_ID={n + 1000:024x}"


def arrive(page, base: str, n: int):
    page.goto(f"{base}/study/demo/start?{entry(n)}")


def test_declining_and_leaving_return_to_prolific_with_their_codes(prolific_server):
    from playwright.sync_api import sync_playwright

    base = prolific_server
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        declines = new_context(browser).new_page()
        arrive(declines, base, 1)
        declines.click("text=I do not agree")
        declines.wait_for_selector("#platform-link")
        assert declines.get_attribute("#platform-link", "href") == PROLIFIC + "DEMO-NOCONSENT"

        leaves = new_context(browser).new_page()
        start(leaves, base, "", query=entry(2))
        screenshot(leaves, "trial-with-leave-link")
        leaves.click("a.leave-link")
        leaves.wait_for_selector("body[data-step=leave]")
        leaves.click("button[name=leave]")
        leaves.wait_for_selector("#platform-link")
        screenshot(leaves, "left-the-study")
        assert leaves.inner_text("#completion-code") == "DEMO-RETURNED"
        assert leaves.get_attribute("#platform-link", "href") == PROLIFIC + "DEMO-RETURNED"
        browser.close()
