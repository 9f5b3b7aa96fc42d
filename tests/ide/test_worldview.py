"""The world view with two robots in two worlds (--robot turtlesim --robot rover), in the IDE in
Chromium: one world drawn at a time, chosen with tabs, scaled to fill its panel, enlarged by a
tap; at tablet and phone sizes."""

from __future__ import annotations

import pytest

from tests.support.ide import PHONE, TABLET

PAD = 8   # the view's margin around the world, in CSS pixels


@pytest.fixture(scope="module")
def two_worlds(start_gateway):
    return start_gateway("--robot", "turtlesim", "--robot", "rover")


def fills(fit: dict) -> bool:
    """The world touches the panel's margin on one axis and fits inside on the other."""
    e = fit["extent"]
    dx, dy = fit["scale"] * (e["x1"] - e["x0"]), fit["scale"] * (e["y1"] - e["y0"])
    room_x, room_y = fit["w"] - 2 * PAD, fit["h"] - 2 * PAD
    return dx <= room_x + 0.5 and dy <= room_y + 0.5 and (abs(dx - room_x) < 0.5 or abs(dy - room_y) < 0.5)


@pytest.mark.parametrize("viewport,name", [(TABLET, "tablet"), (PHONE, "phone")])
def test_one_world_per_view(two_worlds, ide_factory, viewport, name):
    ide = ide_factory(two_worlds)
    page = ide.page
    page.set_viewport_size(viewport)
    page.evaluate("localStorage.removeItem('rosgate.world')")
    page.wait_for_function("rosgateIde.world.worlds().length === 2 && rosgateIde.world.summary().walls > 0")
    worlds = ide.js("rosgateIde.world.worlds()")
    assert worlds == [{"frame": "turtlesim", "robots": ["turtle1"]}, {"frame": "world", "robots": ["rover"]}]

    # the rover's arena first: its walls and the rover, no turtle; 10 x 8 m filling the panel
    assert ide.js("rosgateIde.world.current()") == "world"
    summary = ide.js("rosgateIde.world.summary()")
    assert summary["robots"] == 1 and summary["walls"] >= 4 and summary["bounds"] == 1
    page.wait_for_function("rosgateIde.world.fit && rosgateIde.world.fit.extent.x1 - rosgateIde.world.fit.extent.x0 < 10.5")
    assert fills(ide.js("rosgateIde.world.fit"))
    tabs = page.locator(".world-tabs button")
    assert tabs.count() == 2 and page.is_visible(".world-tabs")
    assert tabs.nth(1).get_attribute("aria-selected") == "true" and tabs.nth(1).inner_text() == "rover"
    ide.screenshot(f"worldview-rover-{name}")

    # the turtle's world: its square alone, scaled up to fill the same panel
    tabs.nth(0).click()
    page.wait_for_function("rosgateIde.world.current() === 'turtlesim'")
    page.wait_for_function("Math.abs(rosgateIde.world.fit.extent.x1 - rosgateIde.world.fit.extent.x0 - 11.0889) < 0.01")
    summary = ide.js("rosgateIde.world.summary()")
    assert summary.get("walls", 0) == 0 and summary["robots"] == 1 and summary["bounds"] == 1
    assert fills(ide.js("rosgateIde.world.fit"))
    assert ide.js("localStorage.getItem('rosgate.world')") == "turtlesim"   # remembered

    # a tap enlarges it over the page; another tap brings it back
    small = page.locator("#world").bounding_box()
    page.click("#world")
    page.wait_for_selector(".world-big canvas")
    big = page.locator(".world-big canvas").bounding_box()
    assert big["width"] * big["height"] > 2 * small["width"] * small["height"]
    assert big["width"] >= 0.95 * viewport["width"] and big["height"] >= 0.9 * viewport["height"]
    ide.screenshot(f"worldview-enlarged-{name}")
    page.click(".world-big")
    page.wait_for_selector(".world-big", state="detached")
    assert not ide.errors, ide.errors
