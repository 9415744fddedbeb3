"""`oocfmt view` by touch and trackpad, in headless chromium with a touch screen: one finger
orbits, two pinch to zoom towards their midpoint, two moving together pan, and a trackpad
pinch (a wheel with ctrl) zooms. Touches go through the DevTools protocol
(`Input.dispatchTouchEvent`), as a tablet's would. Screenshots go under target/browser/."""

import math

from conftest import OUT
from test_view import CANVAS, open_view, settle


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def add(a, b):
    return [x + y for x, y in zip(a, b)]


def mul(a, s):
    return [x * s for x in a]


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def norm(a):
    return mul(a, 1 / math.sqrt(dot(a, a)))


def distance(cam):
    return math.sqrt(dot(sub(cam["look_at"], cam["eye"]), sub(cam["look_at"], cam["eye"])))


def camera(page):
    return page.evaluate("() => window.oocfmt.camera")


class Fingers:
    """Touch points on the page, in CSS pixels of the canvas."""

    def __init__(self, page):
        self.page = page
        self.cdp = page.context.new_cdp_session(page)
        box = page.locator("#frame").bounding_box()
        self.left, self.top = box["x"], box["y"]
        self.width, self.height = box["width"], box["height"]

    def send(self, kind, points):
        touch = [{"x": self.left + x, "y": self.top + y, "id": i} for i, (x, y) in enumerate(points)]
        self.cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": touch})
        # One animation frame between moves, as a finger's events arrive.
        self.page.evaluate("() => new Promise((r) => requestAnimationFrame(() => r()))")

    def gesture(self, start, end, steps=12):
        """Fingers down at `start`, moved in `steps` to `end`, lifted."""
        self.send("touchStart", start)
        for s in range(1, steps + 1):
            t = s / steps
            self.send("touchMove", [(a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t) for a, b in zip(start, end)])
        self.send("touchEnd", [])


def on_screen(page, p):
    return page.evaluate("(p) => window.oocfmt.onScreen(p)", p)


def through(page, cam, x, y, depth):
    """The point at `depth` in front of `cam` (along its view axis) on its ray through canvas
    pixel (x, y) (device pixels are CSS pixels here), as the page computes its rays."""
    w, h = page.evaluate("() => [document.getElementById('frame').width, document.getElementById('frame').height]")
    f = norm(sub(cam["look_at"], cam["eye"]))
    r = norm(cross(f, cam["up"]))
    u = cross(r, f)
    pixel = 2 * math.tan(math.radians(cam["fov_y"]) / 2) / h
    d = add(f, add(mul(r, (x - w / 2) * pixel), mul(u, (h / 2 - y) * pixel)))
    return add(cam["eye"], mul(d, depth))


def test_one_finger_orbits_the_view(touch_page, server):
    page = touch_page
    first = open_view(page, server)
    page.wait_for_function("() => location.hash.includes('eye=')")
    before = page.evaluate(CANVAS)
    hash_before = page.evaluate("() => location.hash")
    cam = camera(page)
    fingers = Fingers(page)
    cx, cy = fingers.width / 2, fingers.height / 2
    fingers.gesture([(cx, cy)], [(cx + 120, cy + 30)])
    settle(page, first["seq"] + 1)
    page.wait_for_function("(h) => location.hash !== h", arg=hash_before)
    moved = camera(page)
    # An orbit: the eye turned about the look-at point, at the same distance.
    assert moved["eye"] != cam["eye"] and moved["look_at"] == cam["look_at"]
    assert abs(distance(moved) - distance(cam)) < 1e-9 * distance(cam)
    assert page.evaluate(CANVAS)["hash"] != before["hash"], "the picture did not change"
    assert page.evaluate("() => window.oocfmt.picks.length") == 0, "a drag is no tap"
    page.screenshot(path=str(OUT / "view-touch-orbited.png"))


def test_a_pinch_zooms_to_its_midpoint_and_two_fingers_pan(touch_page, server):
    page = touch_page
    first = open_view(page, server)
    cam = camera(page)
    fingers = Fingers(page)
    # Off the centre, so that zooming to the midpoint differs from zooming to the centre.
    mx, my = fingers.width * 0.4, fingers.height * 0.6
    mark = through(page, cam, mx, my, 3 * distance(cam))
    fingers.gesture([(mx - 40, my), (mx + 40, my)], [(mx - 100, my), (mx + 100, my)])
    settle(page, first["seq"] + 1)
    zoomed = camera(page)
    # Fingers 80 pixels apart, then 200: the orbit distance shrinks 2.5 times.
    assert abs(distance(zoomed) / distance(cam) - 0.4) < 0.01, (cam, zoomed)
    # The point under the midpoint stayed under it.
    x, y = on_screen(page, mark)
    assert abs(x - mx) < 1.0 and abs(y - my) < 1.0, ((x, y), (mx, my))
    assert page.evaluate("() => window.oocfmt.picks.length") == 0, "a pinch is no tap"
    page.screenshot(path=str(OUT / "view-touch-pinched.png"))
    # Two fingers moving together pan: the view keeps its direction and distance, and the
    # point under them follows them.
    seq = page.evaluate("() => window.oocfmt.last.seq")
    mark = through(page, zoomed, mx, my, distance(zoomed))
    fingers.gesture([(mx - 50, my), (mx + 50, my)], [(mx - 10, my - 60), (mx + 90, my - 60)])
    settle(page, seq + 1)
    panned = camera(page)
    assert panned["look_at"] != zoomed["look_at"]
    assert abs(distance(panned) - distance(zoomed)) < 1e-9 * distance(zoomed)
    f0 = norm(sub(zoomed["look_at"], zoomed["eye"]))
    f1 = norm(sub(panned["look_at"], panned["eye"]))
    assert dot(f0, f1) > 1 - 1e-12, (f0, f1)
    x, y = on_screen(page, mark)
    assert abs(x - (mx + 40)) < 1.0 and abs(y - (my - 60)) < 1.0, ((x, y), (mx + 40, my - 60))
    page.screenshot(path=str(OUT / "view-touch-panned.png"))
    # One finger held still while the other moves away: still a pinch, and the still finger,
    # lifted last, is no tap.
    seq = page.evaluate("() => window.oocfmt.last.seq")
    fingers.gesture([(mx + 40, my), (mx, my)], [(mx + 100, my), (mx, my)])
    settle(page, seq + 1)
    assert abs(distance(camera(page)) / distance(panned) - 0.4) < 0.01
    page.wait_for_timeout(500)
    assert page.evaluate("() => window.oocfmt.picks.length") == 0, "the pinch picked"


def test_a_trackpad_pinch_zooms(touch_page, server):
    page = touch_page
    first = open_view(page, server)
    cam = camera(page)
    box = page.locator("#frame").bounding_box()
    cdp = page.context.new_cdp_session(page)
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    # Chromium sends a trackpad pinch as a wheel with ctrl held (modifiers 2), in small steps.
    for _ in range(5):
        cdp.send("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": x, "y": y, "deltaX": 0, "deltaY": -10, "modifiers": 2})
    settle(page, first["seq"] + 1)
    zoomed = camera(page)
    # Each step of 10 pixels zooms by e^0.1.
    assert abs(distance(zoomed) / distance(cam) - math.exp(-0.5)) < 0.01, (cam, zoomed)
    # Zoomed in at the centre: the view direction kept.
    f0 = norm(sub(cam["look_at"], cam["eye"]))
    f1 = norm(sub(zoomed["look_at"], zoomed["eye"]))
    assert dot(f0, f1) > 1 - 1e-6
