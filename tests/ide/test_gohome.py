"""The rover dashboard's "enough charge to get home?": the estimate from a driven path and the
battery it used, in Chromium, on made-up readings and then on the live rover."""

from __future__ import annotations

from tests.support.ide import TABLET, open_teleop

ESTIMATE = """async ([start, pcts]) => {
  const { HomeEstimate } = await import('./js/teleop/gohome.js');
  const el = document.createElement('p');
  const h = new HomeEstimate(el);
  const odom = (x, y) => h.odom({ pose: { pose: { position: { x, y, z: 0 } } } });
  odom(0, 0);
  h.battery({ percentage: start });
  for (let i = 1; i <= 100; i++) odom(i * 0.1, 0);          // 10 m out, straight
  h.battery({ percentage: pcts[0] });
  const out = [{ ...h.estimate(), text: el.textContent, level: el.dataset.level }];
  for (let i = 1; i <= 50; i++) odom(10 - i * 0.1, 0);     // 5 m back the same way: 5 m left to go
  h.battery({ percentage: pcts[1] });
  out.push({ ...h.estimate(), text: el.textContent, level: el.dataset.level });
  return out;
}"""


def test_the_estimate_follows_the_path_and_the_consumption(chromium, rover):
    gw, _ = rover
    ctx, page, errors = open_teleop(chromium, gw, viewport=TABLET)
    try:
        # 10 % used over 10 m: 1 % a metre; back 10 m needs 12.5 % with the margin
        out, back = page.evaluate(ESTIMATE, [0.9, [0.8, 0.75]])
        assert abs(out['back'] - 10) < 0.05 and abs(out['need'] - 12.5) < 0.1, out
        assert out['level'] == 'ok' and 'enough to get home' in out['text']
        # 15 % over 15 m, 5 m back left along the path: needs 6.25 %, has 75 %
        assert abs(back['back'] - 5) < 0.15 and abs(back['need'] - 6.25) < 0.2, back
        # the same trip with little charge left: it warns, then says turn back now
        low = page.evaluate(ESTIMATE, [0.3, [0.2, 0.19]])   # 7.5 % to spare, then 14.4 %
        assert low[0]['level'] == 'warn' and 'turn back soon' in low[0]['text'], low[0]
        assert low[1]['level'] == 'ok'
        worse = page.evaluate(ESTIMATE, [0.25, [0.15, 0.1]])   # 2.5 % to spare
        assert worse[0]['level'] == 'danger' and 'turn back now' in worse[0]['text'], worse[0]

        # live: driving the rover gives a distance back and, once measured, a need
        page.fill("#maxspeed", "0.8")
        page.dispatch_event("#maxspeed", "input")
        page.keyboard.down("ArrowUp")
        page.wait_for_function("teleop.home.driven > 1.5", timeout=30000)
        page.keyboard.up("ArrowUp")
        page.wait_for_function("/home \\d+\\.\\d m back/.test(document.querySelector('#home').textContent)")
        page.wait_for_function("teleop.home.estimate().need > 0", timeout=30000)
        assert 'needs' in page.inner_text('#home')
        assert not errors, errors
    finally:
        ctx.close()
