"""`oocfmt view` in a real browser (headless Debian chromium): the page loads and shows a
frame, a drag changes the picture, keys fly, a click prints a distance, the URL hash
round-trips the view, a wrong token is refused, the screenshot button downloads the frame and bookmarks replay with
`render --path`. Screenshots are saved under target/browser/."""

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
    page.keyboard.press("b")
    page.keyboard.press("2")  # the top view
    settle(page, page.evaluate("() => window.oocfmt.last.seq") + 1)
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
