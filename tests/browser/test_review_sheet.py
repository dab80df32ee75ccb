"""The labelling helper's review sheet in a real browser (headless Chromium driven by Selenium):
the page a person opens shows every frame and its pictures, a correction made in its form comes
out in the labels it makes, and those labels, accepted into the folder, score the pipeline by
exactly the corrections. Run by ``make test-browser`` (Chromium and its driver are Debian
packages: ``make browser-deps``)."""

import json
import shutil

import pytest

pytestmark = pytest.mark.browser

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")


@pytest.fixture(scope="module")
def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    assert CHROMIUM and DRIVER, "make browser-deps installs chromium and chromium-driver"
    opts = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        opts.add_argument(a)
    opts.binary_location = CHROMIUM
    d = webdriver.Chrome(service=Service(DRIVER), options=opts)
    yield d
    d.quit()


def test_a_correction_made_on_the_sheet_is_what_eval_scores(cli, smoke, tmp_path, browser):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    folder = tmp_path / "frames"
    folder.mkdir()
    for name in ("000000.png", "000001.png", "000002.png"):
        shutil.copy(smoke / "frames" / name, folder / name)
    dark = smoke / "dark" / "webcam.png"
    code, out, err = cli("label", folder, "--dark", dark, "--out", tmp_path / "sheet", "--json")
    assert code == 0, err
    proposed = [json.loads(x) for x in (tmp_path / "sheet" / "proposed.jsonl").read_text().splitlines()]

    browser.get((tmp_path / "sheet" / "index.html").as_uri())
    sections = browser.find_elements(By.CSS_SELECTOR, "section.frame")
    assert len(sections) == 3
    sizes = browser.execute_script("return Array.from(document.images).map(i => i.naturalWidth)")
    assert len(sizes) == 6 and all(s > 0 for s in sizes)  # each frame and its ground view load
    was = proposed[0]["boxes"]["2"]
    Select(sections[0].find_element(By.NAME, "box-2")).select_by_value("false" if was else "true")
    Select(sections[1].find_element(By.NAME, "box-1")).select_by_value("null")
    heading = sections[2].find_element(By.NAME, "heading")
    heading.clear()
    heading.send_keys("1.5")
    browser.find_element(By.ID, "make").click()
    text = browser.find_element(By.ID, "labels").get_attribute("value")
    made = [json.loads(x) for x in text.splitlines()]
    assert made[0]["boxes"]["2"] is (not was) and made[1]["boxes"]["1"] is None
    assert made[2]["heading_error_deg"] == 1.5 and made[0]["dots"] == proposed[0]["dots"]

    (tmp_path / "labels.jsonl").write_text(text)
    assert cli("label", folder, "--accept", tmp_path / "labels.jsonl")[0] == 0
    code, out, err = cli("eval", folder, "--dark", dark, "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["boxes_scored"] == 3 * 5 - 1  # box 1 of the second frame left out
    assert r["box_accuracy"] == pytest.approx((r["boxes_scored"] - 1) / r["boxes_scored"])  # the flipped box
    assert r["dot_recall"] == 1.0 and r["dot_precision"] == 1.0  # the proposed dots are the found ones
