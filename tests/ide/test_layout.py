"""The IDE on a tablet (1180 x 820) and a phone (390 x 844), in Chromium with touch: flyouts
leave the workspace usable, "wait" and "stop the robot" show without scrolling, a Twist publish
block fits, the code panel folds and wraps, programs open zoomed to fit; on a phone the page
scrolls to the console and a run works. Screenshots go to tests/ide/artifacts/."""

from __future__ import annotations

from tests.support.ide import PHONE as PHONE_VIEWPORT, TABLET as TABLET_VIEWPORT, IdePage, ex, program

TABLET = {"viewport": TABLET_VIEWPORT, "has_touch": True, "device_scale_factor": 1}
PHONE = {"viewport": PHONE_VIEWPORT, "has_touch": True, "is_mobile": True, "device_scale_factor": 1}


FLYOUTS = """() => {
  const ws = rosgateIde.workspace, tb = ws.getToolbox(), out = {};
  for (const item of tb.getToolboxItems()) {
    if (!item.getName || !item.getName()) continue;
    tb.setSelectedItem(item);
    const f = ws.getFlyout();
    out[item.getName()] = {width: f.getWidth(), view: ws.getMetrics().viewWidth};
  }
  tb.clearSelection();
  return out;
}"""

BLOCK_RECT = """(type) => {
  const fw = rosgateIde.workspace.getFlyout().getWorkspace();
  const b = fw.getTopBlocks(false).find((b) => b.type === type);
  const r = b.getSvgRoot().getBoundingClientRect();
  return {top: r.top, bottom: r.bottom, left: r.left, right: r.right, height: innerHeight, width: innerWidth};
}"""


def select_category(ide: IdePage, name: str):
    ide.js("""(name) => { const tb = rosgateIde.workspace.getToolbox();
      tb.setSelectedItem(tb.getToolboxItems().find((i) => i.getName?.() === name)); }""", name)


def test_tablet_flyouts_leave_room_and_show_wait_and_stop(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway, **TABLET)
    flyouts = ide.js(FLYOUTS)
    assert len(flyouts) >= 10
    for name, f in flyouts.items():
        assert f["width"] <= 0.6 * f["view"], f"the {name} flyout covers {f['width']:.0f} of {f['view']:.0f} px"
        assert f["view"] - f["width"] >= 280, (name, f)
    select_category(ide, "ROS")
    for block in ("ros_sleep", "ros_stop"):
        r = ide.js(BLOCK_RECT, block)
        assert 0 <= r["top"] and r["bottom"] <= r["height"] and r["right"] <= r["width"], (block, r)
    ide.screenshot("ide-tablet-1180x820-ros-flyout")
    assert not ide.errors, ide.errors


def test_tablet_twist_publish_fits_and_code_folds(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway, **TABLET)
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.block(
        "ros_publish", {"TOPIC": "/turtle1/cmd_vel", "TYPE": "geometry_msgs/msg/Twist"}, id="pub")))
    # the message block of the topic's type comes from the live graph
    ide.page.wait_for_function("""() => { const m = rosgateIde.workspace.getBlockById('pub').getInputTargetBlock('MSG');
      return m && m.msgType === 'geometry_msgs/msg/Twist' && m.getInputTargetBlock('F_linear'); }""")
    fit = ide.js("""() => { const ws = rosgateIde.workspace, b = ws.getBlockById('pub');
      const r = b.getSvgRoot().getBoundingClientRect();
      const lin = b.getInputTargetBlock('MSG').getInputTargetBlock('F_linear');
      return {width: r.width, view: ws.getMetrics().viewWidth, inline: lin.getInputsInline(), scale: ws.scale}; }""")
    assert fit["inline"], "a Vector3 sits on one row"
    assert fit["width"] <= 0.75 * fit["view"], fit
    ide.screenshot("ide-tablet-1180x820-twist")

    # long lines wrap in the code panel; the panel folds away and the console takes its room
    ide.load_example("wall_follower.json")
    ide.page.wait_for_function("document.querySelector('#code-python').textContent.includes('rt.publish')")
    wrap = ide.js("(() => { const p = document.querySelector('#code-python'); return [p.scrollWidth, p.clientWidth]; })()")
    assert wrap[0] <= wrap[1] + 1, wrap
    console_before = ide.js("document.querySelector('#console').getBoundingClientRect().height")
    ide.page.click("#code-toggle")
    assert not ide.page.is_visible("#code-python")
    assert ide.js("document.querySelector('#console').getBoundingClientRect().height") > console_before + 100
    ide.page.click("#code-toggle")
    assert ide.page.is_visible("#code-python")
    assert not ide.errors, ide.errors


def test_programs_open_zoomed_to_fit(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway, **TABLET)
    for example in ("drive_square.json", "three_turtles.json", "pid_goal.json"):
        ide.load_example(example)
        view = ide.js("""() => { const ws = rosgateIde.workspace;
          const box = ws.getBlocksBoundingBox(), v = ws.getMetricsManager().getViewMetrics(true);
          return {box: [box.left, box.top, box.right, box.bottom], view: [v.left, v.top, v.left + v.width, v.top + v.height],
                  scale: ws.scale}; }""")
        left, top, right, bottom = view["box"]
        vl, vt, vr, vb = view["view"]
        assert 0.5 <= view["scale"] <= 0.8, (example, view)
        assert vl - 1 <= left and vt - 1 <= top, (example, view)          # its start is in sight
        if view["scale"] > 0.5:                                              # the whole program shows
            assert right <= vr + 1 and bottom <= vb + 1, (example, view)
    ide.load_example("three_turtles.json")
    ide.screenshot("ide-tablet-1180x820")


def test_phone_scrolls_to_the_console_and_runs(turtle_gateway, ide_factory):
    ide = ide_factory(turtle_gateway, **PHONE)
    ide.screenshot("ide-phone-390x844")
    sizes = ide.js("[document.scrollingElement.scrollHeight, innerHeight, innerWidth, document.scrollingElement.scrollWidth]")
    assert sizes[0] > sizes[1], "the page scrolls"
    assert sizes[3] <= sizes[2], "and not sideways"
    ws = ide.js("[rosgateIde.workspace.getMetrics().viewWidth, innerWidth]")
    assert ws[0] >= 0.9 * ws[1], f"the categories go along the top on a phone: {ws}"
    ide.js("(p) => rosgateIde.loadProgram(p)", program(ex.log(ex.text("hello from a phone"))))
    ide.page.tap("#run")
    ide.wait_idle(timeout=15)
    ide.page.locator("#console").scroll_into_view_if_needed()
    box = ide.js("(() => { const r = document.querySelector('#console').getBoundingClientRect(); return [r.top, r.bottom, innerHeight]; })()")
    assert 0 <= box[0] and box[1] <= box[2] + 1, box
    assert ide.page.locator("#console-lines .line.log", has_text="hello from a phone").is_visible()
    ide.screenshot("ide-phone-390x844-console")
    assert not ide.errors, ide.errors
