"""`oocfmt view` in a real browser (headless Debian chromium): the page loads and shows a
frame, a drag changes the picture, keys fly, a click prints a distance, the URL hash
round-trips the view, a wrong token is refused, the screenshot button downloads the frame and bookmarks replay with
`render --path`, a section plane cuts the picture (along an axis, flipped, through a
pick), and the model tree of a file with parts opens lazily, hides, isolates and marks the
picked part. Screenshots are saved under target/browser/."""

import json
import subprocess

from conftest import OUT

SETTLED = "(seq) => { const l = window.oocfmt && window.oocfmt.last; return !!l && l.figures.last && l.seq >= seq; }"

# A digest of the canvas: an FNV-1a hash of its pixels and the share of pixels that differ from
# the top-left one (the background) by more than a few levels.
CANVAS = """() => {
  const c = document.getElementById('frame');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let h = 2166136261 >>> 0, model = 0;
  for (let i = 0; i < d.length; i += 4) {
    for (let k = 0; k < 3; k++) h = Math.imul(h ^ d[i + k], 16777619) >>> 0;
    if (Math.abs(d[i] - d[0]) + Math.abs(d[i + 1] - d[1]) + Math.abs(d[i + 2] - d[2]) > 12) model++;
  }
  return { hash: h, model: model / (d.length / 4), width: c.width, height: c.height };
}"""


def settle(page, seq=0):
    page.wait_for_function(SETTLED, arg=seq, timeout=30_000)
    return page.evaluate("() => window.oocfmt.last")


def open_view(page, url):
    resp = page.goto(url)
    assert resp.status == 200
    return settle(page)


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def test_the_page_loads_and_shows_a_frame(page, server):
    last = open_view(page, server)
    f = last["figures"]
    assert last["format"] == "png" and f["last"] and f["samples"] == f["spp"] == 4
    canvas = page.evaluate(CANVAS)
    assert (canvas["width"], canvas["height"]) == (f["width"], f["height"])
    assert 0.05 < canvas["model"] < 0.95, canvas
    status = page.inner_text("#status")
    for word in ["frame", "fps", "PoE 0", "4/4 spp", "full detail", "cache", "pending", "loaded/s"]:
        assert word in status, status
    assert "mb.oocf" in page.inner_text("#title")
    page.screenshot(path=str(OUT / "view-loaded.png"))


def test_a_drag_changes_the_picture(page, server):
    first = open_view(page, server)
    before = page.evaluate(CANVAS)
    eye = page.evaluate("() => window.oocfmt.camera.eye")
    box = page.locator("#frame").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 150, y + 40, steps=10)
    page.mouse.up()
    last = settle(page, first["seq"] + 1)
    assert last["seq"] > first["seq"]
    after = page.evaluate(CANVAS)
    assert after["hash"] != before["hash"]
    assert page.evaluate("() => window.oocfmt.camera.eye") != eye
    page.screenshot(path=str(OUT / "view-dragged.png"))


def test_keys_fly_forward(page, server):
    first = open_view(page, server)
    cam = page.evaluate("() => window.oocfmt.camera")
    page.focus("#view")
    page.keyboard.down("w")
    page.wait_for_timeout(400)
    page.keyboard.up("w")
    settle(page, first["seq"] + 1)
    moved = page.evaluate("() => window.oocfmt.camera")
    forward = sub(cam["look_at"], cam["eye"])
    step = sub(moved["eye"], cam["eye"])
    assert dot(step, forward) > 0, (cam, moved)
    # Flying keeps the direction: the look-at point moved with the eye.
    assert sub(moved["look_at"], moved["eye"]) == forward or abs(
        dot(sub(moved["look_at"], moved["eye"]), forward) - dot(forward, forward)
    ) < 1e-6 * dot(forward, forward)


def test_the_url_hash_round_trips_the_view(page, server, browser):
    first = open_view(page, server)
    box = page.locator("#frame").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down(button="right")
    page.mouse.move(x - 40, y + 25, steps=5)
    page.mouse.up(button="right")
    page.mouse.wheel(0, -200)
    settle(page, first["seq"] + 1)
    page.wait_for_function("() => location.hash.includes('eye=')")
    page.wait_for_timeout(300)
    camera = page.evaluate("() => window.oocfmt.camera")
    link = page.evaluate("() => location.href")
    assert "#eye=" in link and "token=" in link
    assert page.evaluate("() => location.hash") == page.evaluate(
        "() => '#eye=' + window.oocfmt.camera.eye.join(',') + '&look=' + window.oocfmt.camera.look_at.join(',')"
        " + '&up=' + window.oocfmt.camera.up.join(',') + '&fov=' + window.oocfmt.camera.fov_y"
    )
    here = page.evaluate(CANVAS)
    other = page.context.new_page()
    other.goto(link)
    settle(other)
    assert other.evaluate("() => window.oocfmt.camera") == camera
    assert other.evaluate(CANVAS) == here, "the link shows another picture"
    other.screenshot(path=str(OUT / "view-from-link.png"))
    other.close()


def test_a_wrong_token_is_refused(page, server):
    good = server.split("token=")[1]
    wrong = server.replace(good, "0" * len(good))
    resp = page.goto(wrong)
    assert resp.status == 403
    resp = page.goto(server.split("?")[0])
    assert resp.status == 401
    # From the right page, a socket with a wrong token does not open.
    open_view(page, server)
    outcome = page.evaluate(
        """() => new Promise((done) => {
            const w = new WebSocket(`ws://${location.host}/ws?token=bad`);
            w.onopen = () => done('open');
            w.onerror = () => done('refused');
        })"""
    )
    assert outcome == "refused"


def test_screenshot_downloads_the_frame_and_bookmarks_replay_with_render(page, server, oocfmt, model):
    open_view(page, server)
    with page.expect_download() as d:
        page.click("#shot")
    shot = OUT / "view-download.png"
    d.value.save_as(str(shot))
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page.focus("#view")
    # The frame count before the key: read after it, the new view's last frame may already be
    # in, and the wait would be for one that never comes.
    seq = page.evaluate("() => window.oocfmt.last.seq")
    page.keyboard.press("b")
    page.keyboard.press("2")  # the top view
    settle(page, seq + 1)
    page.keyboard.press("b")
    assert page.inner_text("#marks") == "2"
    path = OUT / "bookmarks.json"
    path.write_text(page.evaluate("() => window.oocfmt.pathJson()"))
    assert len(json.loads(path.read_text())) == 2
    out = OUT / "bookmarks.png"
    r = subprocess.run(
        [oocfmt, "render", str(model), "-o", str(out), "--path", str(path), "--size", "96x72"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert (OUT / "bookmarks-0000.png").exists() and (OUT / "bookmarks-0001.png").exists()


def test_a_click_prints_a_distance_and_two_measure(page, server):
    first = open_view(page, server)
    box = page.locator("#frame").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.click(x, y)
    page.wait_for_function("() => window.oocfmt.picks.length === 1")
    text = page.inner_text("#pick")
    assert "distance" in text and "point (" in text and "normal (" in text, text
    hit = page.evaluate("() => window.oocfmt.picks[0].hit")
    assert hit is not None and hit["distance"] > 0
    # A click does not turn the view: no new camera was sent.
    assert page.evaluate("() => window.oocfmt.last.seq") == first["seq"]
    page.mouse.click(x + 12, y + 8)
    page.wait_for_function("() => window.oocfmt.picks.length === 2")
    assert "from the pick before" in page.inner_text("#pick")
    page.screenshot(path=str(OUT / "view-picked.png"))
    page.mouse.click(box["x"] + 3, box["y"] + 3)
    page.wait_for_function("() => window.oocfmt.picks.length === 3")
    assert "nothing there" in page.inner_text("#pick")


# The newest frame arrived after the first `n` and is the still view's last, and it is drawn.
SETTLED_AFTER = """(n) => {
  const o = window.oocfmt, h = o.history;
  if (o.frames <= n || !h.length) return false;
  const e = h[h.length - 1];
  return e.header.figures.last && o.last === e.header;
}"""


def settle_after(page, n):
    page.wait_for_function(SETTLED_AFTER, arg=n, timeout=30_000)
    return page.evaluate(CANVAS)


def frames(page):
    return page.evaluate("() => window.oocfmt.frames")


def slide(page, value):
    page.evaluate(
        "(v) => { const s = document.getElementById('section-pos'); s.value = String(v); s.dispatchEvent(new Event('input')); }",
        value,
    )


def test_a_section_plane_cuts_the_picture_flips_and_goes_through_a_pick(page, server):
    open_view(page, server)
    whole = page.evaluate(CANVAS)
    n = frames(page)
    page.select_option("#section-axis", "x")
    half = settle_after(page, n)
    plane = page.evaluate("() => window.oocfmt.section")
    assert plane["normal"] == [1, 0, 0], plane
    assert half["hash"] != whole["hash"]
    assert "x ≥" in page.inner_text("#section-value")
    page.screenshot(path=str(OUT / "view-section.png"))
    # At the box's high end the plane keeps nothing: the background.
    n = frames(page)
    slide(page, 1000)
    empty = settle_after(page, n)
    assert empty["model"] < 0.005, empty
    # Flipped it keeps everything again.
    n = frames(page)
    page.click("#section-flip")
    kept = settle_after(page, n)
    assert page.evaluate("() => window.oocfmt.section.normal") == [-1, 0, 0]
    assert abs(kept["model"] - whole["model"]) < 0.01, (kept, whole)
    # Through a picked point, along its normal: the picked surface is cut away.
    box = page.locator("#frame").bounding_box()
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.wait_for_function("() => window.oocfmt.picks.length === 1")
    hit = page.evaluate("() => window.oocfmt.picks[0].hit")
    assert hit is not None
    n = frames(page)
    page.select_option("#section-axis", "pick")
    through = settle_after(page, n)
    plane = page.evaluate("() => window.oocfmt.section")
    assert dot(plane["normal"], hit["normal"]) < -0.999, (plane, hit)
    assert through["model"] > 0.01, through
    page.screenshot(path=str(OUT / "view-section-pick.png"))
    # The same pixel picked again sees past the surface that was there: farther, or nothing.
    page.evaluate("() => { const p = window.oocfmt.picks[0]; window.oocfmt.send({ type: 'pick', seq: 99, x: p.x, y: p.y }); }")
    page.wait_for_function("() => window.oocfmt.picks.length === 2")
    again = page.evaluate("() => window.oocfmt.picks[1].hit")
    assert again is None or again["distance"] > hit["distance"], (again, hit)
    # Off: the whole model, as before.
    n = frames(page)
    page.select_option("#section-axis", "")
    back = settle_after(page, n)
    assert page.evaluate("() => window.oocfmt.section") is None
    assert abs(back["model"] - whole["model"]) < 0.01, (back, whole)


def test_the_model_tree_opens_lazily_hides_isolates_and_marks_the_picked_part(page, cad_server):
    open_view(page, cad_server)
    page.wait_for_function("() => window.oocfmt.tree.rows > 0")
    whole = page.evaluate(CANVAS)
    top = page.evaluate("() => window.oocfmt.tree.rows")
    # Only the top level is there until a part is opened.
    first = page.locator("#tree-rows > .part > .line").first
    first.locator(".toggle").click()
    page.wait_for_function("(n) => window.oocfmt.tree.rows > n", arg=top)
    assert page.locator("#tree-rows > .part").first.locator(".kids > .part").count() > 0
    # Hiding the first top-level part changes the picture; showing all brings it back.
    n = frames(page)
    first.locator("input[type=checkbox]").uncheck()
    hidden = settle_after(page, n)
    assert page.evaluate("() => window.oocfmt.tree.hidden") == [int(first.get_attribute("data-id"))]
    assert hidden["hash"] != whole["hash"]
    page.screenshot(path=str(OUT / "view-tree-hidden.png"))
    n = frames(page)
    page.click("#tree-all")
    back = settle_after(page, n)
    assert back["hash"] == whole["hash"]
    # Isolating one part shows less of the model than the whole.
    n = frames(page)
    first.locator("button", has_text="isolate").click()
    alone = settle_after(page, n)
    assert alone["model"] < whole["model"], (alone, whole)
    n = frames(page)
    page.click("#tree-all")
    settle_after(page, n)
    # A pick opens the tree down to the picked part and marks it.
    box = page.locator("#frame").bounding_box()
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.wait_for_function("() => window.oocfmt.picks.length === 1")
    pick = page.evaluate("() => window.oocfmt.picks[0]")
    assert pick["hit"] is not None and pick["lineage"], pick
    part = pick["lineage"][-1]
    assert pick["hit"]["part"] == part
    page.wait_for_selector(f"#tree .line.picked[data-id='{part}']", timeout=10_000)
    assert page.evaluate("() => window.oocfmt.tree.picked") == part
    page.screenshot(path=str(OUT / "view-tree-picked.png"))
    # An id past the part table is refused and changes nothing.
    page.evaluate("() => window.oocfmt.send({ type: 'parts', hide: [100000] })")
    page.wait_for_function("() => window.oocfmt.errors.some((e) => e.includes('parts refused'))")


# The screen distance, in CSS pixels, from pick `m`'s pixel to each corner of its triangle.
CORNER_PX = """(m) => {
  const c = document.getElementById('frame');
  const scale = c.width / c.clientWidth;
  return m.hit.corners.map((p) => {
    const s = window.oocfmt.onScreen(p);
    return s ? Math.hypot(s[0] - (m.x + 0.5), s[1] - (m.y + 0.5)) / scale : 1e9;
  });
}"""


def test_a_measure_snaps_to_a_vertex_within_a_few_pixels(page, cad_server):
    open_view(page, cad_server)
    page.click("#tree-toggle")  # the tree off the picture
    box = page.locator("#frame").bounding_box()
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.wait_for_function("() => window.oocfmt.picks.length === 1")
    first = page.evaluate("() => window.oocfmt.picks[0]")
    assert first["hit"] and first["hit"]["corners"], first
    # Snapped exactly when a corner is within 6 pixels of the click.
    d = page.evaluate(CORNER_PX, first)
    assert first["snapped"] == (min(d) <= 6), (first, d)
    # Clicks 2 pixels from each corner of that triangle, towards its middle: each snaps
    # exactly when a corner of what it hit is within 6 pixels, and one that lands on the same
    # triangle (another surface may cover a corner) snaps to a vertex of it.
    on = [page.evaluate("(p) => window.oocfmt.onScreen(p)", c) for c in first["hit"]["corners"]]
    mid = [sum(p[k] for p in on) / 3 for k in range(2)]
    width = page.evaluate("() => document.getElementById('frame').width")
    scale = box["width"] / width
    same = 0
    for k, corner in enumerate(on):
        cx, cy = corner[0] * scale, corner[1] * scale
        dx, dy = mid[0] * scale - cx, mid[1] * scale - cy
        norm = max(1e-9, (dx * dx + dy * dy) ** 0.5)
        step = min(2.0, norm / 2)
        page.mouse.click(box["x"] + cx + dx / norm * step, box["y"] + cy + dy / norm * step)
        page.wait_for_function("(n) => window.oocfmt.picks.length === n", arg=k + 2)
        m = page.evaluate("(n) => window.oocfmt.picks[n]", k + 1)
        if not (m["hit"] and m["hit"]["corners"]):
            continue
        d = page.evaluate(CORNER_PX, m)
        assert m["snapped"] == (min(d) <= 6), (m, d)
        if m["hit"]["triangle"] == first["hit"]["triangle"]:
            same += 1
            assert m["snapped"] and m["measured"] in m["hit"]["corners"], m
            text = page.inner_text("#pick")
            assert "snapped to the vertex" in text and "from the pick before" in text, text
    assert same > 0, "no click landed on the first pick's triangle"
    page.screenshot(path=str(OUT / "view-snapped.png"))
