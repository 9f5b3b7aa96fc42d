"""Kept runs in the pages (ide/js/lab/runhistory.js): the IDE's record switch and "Runs" dialog, and the
class view's runs beside each student's tile, in Chromium against a live gateway with --auth."""

from __future__ import annotations

from tests.support.http import api
from tests.support.ide import drive, ex, page_errors
from tests.support.ide import program as ide_program
from tests.support.lesson import TOKENS, console_says, on_station, open_ide, tokens_file

FETCH = """async (href) => { const r = await fetch(href); const b = new Uint8Array(await r.arrayBuffer());
  return { status: r.status, size: b.length, head: Array.from(b.slice(0, 5)), text: new TextDecoder().decode(b) }; }"""


def test_a_students_kept_run_in_her_ide_and_beside_her_tile(start_gateway, tablets, tmp_path):
    gw = start_gateway("--robot", "turtlesim", "--fleet", "2", "--exclusive-control", "--auth", tokens_file(tmp_path),
                       "--allow-runs", "--cmd-timeout", "0")
    ada = open_ide(tablets(gw, "ada"), gw)
    on_station(ada, "/s01")
    ada.page.wait_for_selector("#run-robot:not([hidden])")
    assert ada.page.is_visible("#run-history") and ada.page.is_visible("#run-record")
    ada.js("(p) => rosgateIde.loadProgram(p)", ide_program(ex.seq(
        ex.block("ros_log", inputs={"VALUE": ex.text("kept for later")}), drive(1.0, 0.5)), name="kept program"))
    ada.page.check("#run-record input")
    ada.page.click("#run-robot")
    console_says(ada, "run r[0-9a-f]+ finished")

    # her Runs dialog: the run, its program, output and recording to download
    ada.page.click("#run-history")
    item = ada.page.wait_for_selector("#dlg-runs li.kept-run")
    run_id = item.get_attribute("data-run")
    assert "kept program" in item.inner_text() and item.get_attribute("data-state") == "finished"
    links = ada.page.eval_on_selector_all("#dlg-runs li.kept-run a", "as => as.map(a => a.getAttribute('href'))")
    assert links == [f"api/runs/{run_id}/source", f"api/runs/{run_id}/output", f"api/runs/{run_id}/recording.mcap"]
    output = ada.page.evaluate(FETCH, links[1])
    assert output["status"] == 200 and "kept for later\n" in output["text"]
    mcap = ada.page.evaluate(FETCH, links[2])
    assert mcap["status"] == 200 and mcap["size"] > 1000 and bytes(mcap["head"]) == b"\x89MCAP"
    source = ada.page.evaluate(FETCH, links[0])
    assert source["status"] == 200 and "kept for later" in source["text"]

    # bo's page lists none of hers, and may not read them
    bo = open_ide(tablets(gw, "bo"), gw)
    bo.page.wait_for_selector("#run-history:not([hidden])")
    bo.page.click("#run-history")
    bo.page.wait_for_selector("#dlg-runs[data-loaded]")
    assert bo.page.query_selector_all("#dlg-runs li.kept-run") == []
    assert bo.page.evaluate(FETCH, links[1])["status"] == 403

    # the teacher's class view: her run beside her tile, with its downloads
    cls = tablets(gw, "teacher").new_page()
    cls.goto(gw.http_url + "class")
    tile = "article.tile[data-ns='/s01']"
    cls.wait_for_selector(f"{tile}[data-owner='ada'] .runs li.kept-run[data-run='{run_id}']", timeout=20000)
    assert cls.eval_on_selector_all(f"{tile} .runs a", "as => as.length") == 3
    assert cls.evaluate(FETCH, links[1])["text"] == output["text"]
    assert cls.query_selector_all("article.tile[data-ns='/s02'] .runs li") == []
    status, body = api(gw, "GET", "/api/runs?all=1", token=TOKENS["teacher"])
    assert status == 200 and [r["owner"] for r in body["runs"]] == ["ada"], body
    assert not page_errors(ada), ada.errors
    assert all('status of 403' in e for e in bo.errors), bo.errors   # her output, which bo asked for above
