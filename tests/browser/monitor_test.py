#!/usr/bin/python3
"""The web monitor in headless Chromium against a real coordinator and worker (ctest label `browser`).

Usage: monitor_test.py TESSERA ARTEFACT_DIR

Timing is driven, never raced: a scripted worker ("holder", plain HTTP) leases tiles and holds them while a real
`tessera worker` renders the rest, so the job page is shown mid-render with known tile states however fast the
machine is; the holder then hands its tiles back and the job finishes. Every wait polls a state with a generous
overall deadline. Exits 77 (ctest SKIP_RETURN_CODE) when Chromium, chromedriver or Selenium is missing.
"""
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

SKIP = 77
DEADLINE = 120.0  # seconds for any one awaited state; only a hung system gets near it

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.common.exceptions import NoSuchElementException, StaleElementReferenceException
except ImportError:
    print("SKIP: python3-selenium is not installed (apt-get install python3-selenium)")
    sys.exit(SKIP)
if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
    print("SKIP: chromium or chromedriver is not installed (apt-get install chromium chromium-driver)")
    sys.exit(SKIP)

TESSERA, ARTEFACTS = sys.argv[1], sys.argv[2]
os.makedirs(ARTEFACTS, exist_ok=True)
WORK = tempfile.mkdtemp(prefix="tessera-browser-")
DOWNLOADS = os.path.join(WORK, "downloads")
PROCS = []

FARM_COMMON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "farm", "common.sh")
WIDTH, HEIGHT = 320, 192
TILE = 32
TOTAL_TILES = (WIDTH // TILE) * (HEIGHT // TILE)
HELD = 3  # tiles the scripted worker holds


def fail(msg):
    raise AssertionError(msg)


def wait_for(what, predicate, deadline=DEADLINE):
    """Polls predicate until it is truthy. The page re-renders while it polls the coordinator, so an element found a
    moment ago may be gone, and one looked for may not be drawn yet: a stale or missing element counts as "not yet"
    and the predicate runs again on a fresh look-up."""
    end = time.monotonic() + deadline
    while True:
        try:
            value = predicate()
        except (StaleElementReferenceException, NoSuchElementException):
            value = None
        if value:
            return value
        if time.monotonic() > end:
            fail("timed out waiting for " + what)
        time.sleep(0.1)


class Http:
    def __init__(self, base, token):
        self.base, self.token = base, token
        self.worker_secret = None  # sent once set: the scripted worker's requests act as it

    def call(self, method, path, body=None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path, data=data, method=method)
        req.add_header("Authorization", "Bearer " + self.token)
        if self.worker_secret:
            req.add_header("X-Tessera-Worker-Secret", self.worker_secret)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(req, timeout=30) as r:
                text = r.read()
                return r.status, (json.loads(text) if text and r.headers.get_content_type() == "application/json" else text)
        except urllib.error.HTTPError as e:
            return e.code, e.read()


def token_file(name):
    path = os.path.join(WORK, name)
    with open(path, "w") as f:
        f.write(os.urandom(24).hex())
    os.chmod(path, 0o600)
    return path, open(path).read()


def start(args, log):
    p = subprocess.Popen(args, stdout=open(os.path.join(WORK, log), "w"), stderr=subprocess.STDOUT)
    PROCS.append(p)
    return p


def stop(p):
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def browser():
    o = webdriver.ChromeOptions()
    o.binary_location = CHROMIUM
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              "--disable-dev-shm-usage", "--window-size=1366,768", "--user-data-dir=" + os.path.join(WORK, "chrome")):
        o.add_argument(a)
    o.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    d = webdriver.Chrome(service=Service(CHROMEDRIVER, log_path=os.path.join(WORK, "chromedriver.log")), options=o)
    # A laptop screen's page area, whatever the headless window's decorations.
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": 1366, "height": 768, "deviceScaleFactor": 1, "mobile": False})
    # Downloads go to a folder of the test's, without asking.
    os.makedirs(DOWNLOADS, exist_ok=True)
    d.execute_cdp_cmd("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": DOWNLOADS})
    return d


def preview_is_the_coordinators(d, job, layer=""):
    """Whether the preview the page shows has the same pixels as the one the coordinator makes now (of `layer`)."""
    return d.execute_async_script("""
        const [job, layer, done] = arguments;
        const pixels = (img) => {
          const c = document.createElement('canvas');
          c.width = img.naturalWidth;
          c.height = img.naturalHeight;
          const g = c.getContext('2d');
          g.drawImage(img, 0, 0);
          return g.getImageData(0, 0, c.width, c.height).data;
        };
        import('/monitor/api.js').then(async (api) => {
          const url = await api.previewUrl(job, layer);
          const now = new Image();
          await new Promise((resolve, reject) => { now.onload = resolve; now.onerror = reject; now.src = url; });
          const a = pixels(document.getElementById('preview')), b = pixels(now);
          URL.revokeObjectURL(url);
          done(a.length === b.length && a.every((v, i) => v === b[i]));
        }).catch((e) => done('error: ' + e));""", job, layer)


def report_failure(d):
    """What the page showed when a check failed: a screenshot, its text and the browser's log."""
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-failure.png"))
    print("page text at the failure:", d.find_element(By.TAG_NAME, "body").text[:2000])
    print("browser log:", d.get_log("browser"))


def console_errors(d):
    return [e for e in d.get_log("browser") if e["level"] == "SEVERE"]


def visible(d, css):
    return [e for e in d.find_elements(By.CSS_SELECTOR, css) if e.is_displayed()]


def click(d, css, what):
    """Clicks the first visible element matching css once it exists (looked up and clicked in one attempt)."""
    def attempt():
        found = visible(d, css)
        if not found:
            return False
        found[0].click()
        return True
    wait_for(what, attempt)


def tiles_in(d, state):
    return len(d.find_elements(By.CSS_SELECTOR, f'#tilemap .tile[data-state="{state}"]'))


def sphere_scene(width=WIDTH, height=HEIGHT):
    """The farm tests' small analytic scene (tests/farm/common.sh, write_sphere_scene)."""
    path = os.path.join(WORK, "scene.json")
    subprocess.run(["bash", "-c", 'source "$1" - - -; write_sphere_scene "$2" "$3" "$4" 4', "bash", FARM_COMMON, path,
                    str(width), str(height)], check=True)
    return json.load(open(path))


def sequence_frames(count, width=WIDTH, height=HEIGHT):
    """A sequence's frames (numbered from 1): the sphere scene with its camera circling the spheres."""
    scene = sphere_scene(width, height)
    frames = []
    for i in range(count):
        s = json.loads(json.dumps(scene))
        a = 0.3 * i
        s["camera"]["position"] = [4 * math.sin(a), 0.6, 4 * math.cos(a)]
        frames.append({"number": i + 1, "scene": s})
    return frames


def selected_frame(d):
    """The number of the frame the strip shows chosen (None when none is)."""
    return d.execute_script(
        "const c = document.querySelector('#frame-strip .frame-cell.selected'); return c ? Number(c.dataset.frame) : null;")


def cell_states(d):
    """The strip's frame number -> state, as the page shows them."""
    return {int(c.get_attribute("data-frame")): c.get_attribute("data-state")
            for c in d.find_elements(By.CSS_SELECTOR, "#frame-strip .frame-cell")}


def thumbnails_shown(d):
    """The frames whose thumbnail the strip shows, loaded."""
    return d.execute_script("""
        return [...document.querySelectorAll('#frame-strip .frame-cell[data-thumb="shown"]')]
          .filter((c) => { const i = c.querySelector('img'); return i && i.complete && i.naturalWidth > 0; })
          .map((c) => Number(c.dataset.frame));""")


def frame_states(client, seq):
    """Frame number -> state of every frame of a sequence, from the API (one page holds them all here)."""
    status, body = client.call("GET", f"/v1/jobs/{seq}/frames")
    if status != 200:
        fail(f"GET /v1/jobs/{seq}/frames answered {status}: {body}")
    return {f["frame"]: f["state"] for f in body["frames"]}


SEQ_FRAMES = 6


def start_worker(base, worker_path, name):
    return start([TESSERA, "worker", "--coordinator", base, "--token-file", worker_path, "--threads", "1",
                  "--name", name, "--cache", os.path.join(WORK, "cache-" + name)], name + ".log")


def check_sequences(d, base, client, workerside, holder, worker_path):
    """Sequences in the monitor: one row in the list with its frames done, the sequence page's frame strip (thumbnails
    of done frames, states of the others), a chosen frame's tile map and image, a frame's download, paging, and frames
    retried from the page. No worker runs when this starts; the scripted worker `holder` keeps a tile where a state
    must hold still."""
    # A 6-frame sequence; the holder takes a tile of frame 1 (frames are leased in order) before any worker runs.
    # It ends in a movie of its frames (the coordinator's ffmpeg, which deploy/install-deps.sh installs).
    status, body = client.call("POST", "/v1/jobs", {"frames": sequence_frames(SEQ_FRAMES), "frame_order": "in_order",
                                                     "tile_size": TILE, "seed": 5, "name": "browser-test sequence",
                                                     "then": ["movie"], "fps": 12})
    if status != 201:
        fail(f"submit of the sequence answered {status}: {body}")
    seq = body["id"]
    status, lease = workerside.call("POST", f"/v1/workers/{holder}/lease")
    frame_jobs = {f["frame"]: f["id"] for f in client.call("GET", f"/v1/jobs/{seq}/frames")[1]["frames"]}
    if status != 200 or lease["job"] != frame_jobs[1]:
        fail(f"the holder did not get a tile of frame 1: {status} {lease}")

    d.get(base + "/#/jobs")
    row = f'tr[data-job="{seq}"]'
    wait_for("the sequence's row, running, no frame done", lambda: any(
        "running" in r.text and "0/6 frames" in r.text for r in visible(d, row)))
    worker = start_worker(base, worker_path, "render-2")
    # Frames 2 to 6 are rendered; frame 1 waits for the held tile.
    wait_for("frames 2-6 done (API)", lambda: client.call("GET", f"/v1/jobs/{seq}")[1]["frames"]["done"] == SEQ_FRAMES - 1)
    row_text = wait_for("5/6 frames in the sequence's row", lambda: next(
        (r.text for r in visible(d, row) if "5/6 frames" in r.text), None))
    # The frames' own job events (they name their sequence) added no rows.
    rows = d.execute_script("return [...document.querySelectorAll('#jobs-table tbody tr')].map((r) => r.dataset.job);")
    if any(r in frame_jobs.values() for r in rows) or rows.count(seq) != 1:
        fail(f"the job list shows a sequence's frames as rows: {rows}")
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-sequence-list.png"))
    print(f"sequence in the list: one row, {row_text.splitlines()}")

    click(d, row, "the sequence's row")
    wait_for("the sequence page", lambda: d.current_url.split("#")[1].startswith(f"/jobs/{seq}/frames"))
    wait_for("6 frames in the strip, 5 done with their thumbnails and frame 1 running", lambda:
             cell_states(d) == {1: "running", **{n: "done" for n in range(2, SEQ_FRAMES + 1)}}
             and sorted(thumbnails_shown(d)) == list(range(2, SEQ_FRAMES + 1)))
    # The running frame is the one chosen: its tile map shows the held tile.
    wait_for("frame 1's tile map with the held tile", lambda: d.find_element(By.ID, "job-title").text == "Frame 1"
             and len(d.find_elements(By.CSS_SELECTOR, "#frame-view #tilemap .tile")) == TOTAL_TILES
             and tiles_in(d, "leased") == 1 and tiles_in(d, "done") == TOTAL_TILES - 1)
    figures = d.find_element(By.ID, "seq-figures").text
    if "5 / 6 done" not in figures or "1 running" not in figures:
        fail(f"the sequence's figures do not count its frames: {figures!r}")
    # The page at a taller window, for the whole of the chosen frame (docs/images/monitor-sequence.png).
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": 1366, "height": 1100, "deviceScaleFactor": 1, "mobile": False})
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-sequence.png"))
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": 1366, "height": 768, "deviceScaleFactor": 1, "mobile": False})

    # The held tile handed back: frame 1 is rendered, and its cell turns into its thumbnail.
    workerside.call("POST", f"/v1/leases/{lease['lease']}/release")
    wait_for("every frame done with its thumbnail", lambda: set(cell_states(d).values()) == {"done"}
             and sorted(thumbnails_shown(d)) == list(range(1, SEQ_FRAMES + 1)))
    wait_for("the sequence done on its page", lambda: "done" in d.find_element(By.ID, "seq-state").text)
    fetched = int(d.find_element(By.ID, "frame-strip").get_attribute("data-thumbs-fetched") or 0)
    if fetched != SEQ_FRAMES:
        fail(f"the strip fetched {fetched} thumbnails for {SEQ_FRAMES} done frames (each once, then from its cache)")
    print(f"sequence page: {SEQ_FRAMES} frames done in the strip, {fetched} thumbnails fetched")
    # The movie step's row names its file once ffmpeg is done; the page's download is the coordinator's movie.
    click(d, '#seq-pipeline #pipe-step-movie [data-output="movie.mp4"]', "the movie's download button")
    saved = os.path.join(DOWNLOADS, "movie.mp4")
    status, movie = client.call("GET", f"/v1/jobs/{seq}/outputs/movie.mp4")
    if status != 200:
        fail(f"the sequence's movie answered {status}")
    wait_for("the downloaded movie", lambda: os.path.exists(saved) and open(saved, "rb").read() == movie)
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-sequence-movie.png"))
    print(f"movie: the step's row offers movie.mp4, downloaded from the page ({len(movie)} bytes, the coordinator's)")

    # Another frame chosen from the strip: its own tile map, image and result.
    click(d, '#frame-strip .frame-cell[data-frame="3"]', "frame 3's cell")
    wait_for("frame 3 chosen", lambda: d.current_url.endswith(f"/jobs/{seq}/frames/3")
             and d.find_element(By.ID, "job-title").text == "Frame 3"
             and selected_frame(d) == 3)
    wait_for("frame 3's tile map, every tile done", lambda: tiles_in(d, "done") == TOTAL_TILES)
    wait_for("frame 3's image", lambda: d.execute_script(
        "const i = document.getElementById('preview'); return !i.hidden && i.complete && i.naturalWidth === arguments[0] "
        "&& i.dataset.tilesDone === String(arguments[1]);", WIDTH, TOTAL_TILES))
    if preview_is_the_coordinators(d, frame_jobs[3]) is not True:
        fail("frame 3's image is not its job's preview")
    click(d, '#frame-view [data-action="download"]', "frame 3's download button")
    saved = os.path.join(DOWNLOADS, "browser-test_sequence.0003.exr")
    wait_for("frame 3's EXR", lambda: os.path.exists(saved) and "Download: " in d.find_element(By.ID, "action-msg").text)
    status, exr = client.call("GET", f"/v1/jobs/{seq}/frames/3/result.exr")
    if status != 200 or open(saved, "rb").read() != exr:
        fail(f"the frame's download is not its result ({status})")
    # A frame's job has no controls of its own besides its download (the sequence's act on it).
    shown = [b.get_attribute("data-action") for b in visible(d, "#frame-view [data-action]")]
    if shown != ["download"]:
        fail(f"a done frame offers {shown}")
    print(f"frame chosen: frame 3's tile map, image and {os.path.basename(saved)} ({len(exr)} bytes)")
    # A frame's job page is its place in its sequence's strip.
    d.get(base + "/#/jobs/" + frame_jobs[5])
    wait_for("frame 5 of the sequence page", lambda: d.current_url.endswith(f"/jobs/{seq}/frames/5")
             and d.find_element(By.ID, "job-title").text == "Frame 5")
    d.get(base + "/#/jobs")
    wait_for("6/6 frames, done, in the list", lambda: any(
        "done" in r.text and "6/6 frames" in r.text for r in visible(d, row)))
    stop(worker)

    # Frames retried from the page. A second sequence; no worker runs: the holder fails frame 1's tile (one worker's
    # failure fails a tile's job here), the sequence is paused and cancelled from its page; frame 4 is retried from
    # its frame's view and is the only one rendered; then the sequence's Retry renders the rest.
    status, body = client.call("POST", "/v1/jobs", {"frames": sequence_frames(SEQ_FRAMES, 64, 64), "tile_size": TILE,
                                                     "seed": 6, "name": "browser-test retry"})
    if status != 201:
        fail(f"submit of the second sequence answered {status}: {body}")
    retried = body["id"]
    status, lease = workerside.call("POST", f"/v1/workers/{holder}/lease")
    if status != 200 or not lease["job"].startswith(retried):
        fail(f"the holder did not get a tile of the second sequence: {status} {lease}")
    workerside.call("POST", f"/v1/leases/{lease['lease']}/fail", {"error": "scene too heavy (scripted)", "log": []})
    d.get(base + f"/#/jobs/{retried}/frames")
    wait_for("frame 1 failed, the others queued", lambda: cell_states(d) == {1: "failed", **{n: "queued" for n in range(2, 7)}})
    click(d, '#seq-actions [data-action="pause"]', "the sequence's pause button")
    wait_for("the frames paused on the page", lambda: cell_states(d) == {1: "failed", **{n: "paused" for n in range(2, 7)}})
    click(d, '#seq-actions [data-action="cancel"]', "the sequence's cancel button")
    click(d, '#seq-actions [data-action="cancel"]', "the cancel confirmation")
    want = {1: "failed", **{n: "cancelled" for n in range(2, 7)}}
    wait_for("the frames cancelled (API)", lambda: frame_states(client, retried) == want)
    wait_for("the frames cancelled on the page", lambda: cell_states(d) == want)
    wait_for("the sequence's retry button for its 6 frames", lambda: any(
        "6 frames" in b.text for b in visible(d, '#seq-actions [data-action="retry"]')))
    click(d, '#frame-strip .frame-cell[data-frame="4"]', "frame 4's cell")
    wait_for("frame 4's view", lambda: d.find_element(By.ID, "job-title").text == "Frame 4")
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-sequence-cancelled.png"))
    click(d, '#frame-view [data-action="retry"]', "frame 4's retry button")
    want[4] = "queued"
    wait_for("frame 4 queued again, and only it (API)", lambda: frame_states(client, retried) == want)
    worker = start_worker(base, worker_path, "render-3")
    want[4] = "done"
    wait_for("frame 4 done with its thumbnail, the others as they were", lambda: cell_states(d) == want
             and thumbnails_shown(d) == [4])
    if frame_states(client, retried) != want:
        fail(f"a retry of frame 4 changed other frames: {frame_states(client, retried)}")
    print("retry of one frame from the page: frame 4 rendered, frame 1 failed and the others cancelled as they were")
    click(d, '#seq-actions [data-action="retry"]', "the sequence's retry button")
    wait_for("every frame done", lambda: set(cell_states(d).values()) == {"done"} and len(thumbnails_shown(d)) == 6)
    wait_for("the sequence done", lambda: "done" in d.find_element(By.ID, "seq-state").text)
    # Deleted from its page, like a job: gone from the list and the API.
    click(d, '#seq-actions [data-action="delete"]', "the sequence's delete button")
    click(d, '#seq-actions [data-action="delete"]', "the delete confirmation")
    wait_for("the job list without the deleted sequence", lambda: d.current_url.endswith("#/jobs")
             and visible(d, row) and not d.find_elements(By.CSS_SELECTOR, f'tr[data-job="{retried}"]'))
    if client.call("GET", f"/v1/jobs/{retried}")[0] != 404:
        fail("the deleted sequence still answers")
    print("retry of the sequence's other frames, then its deletion, from its page")

    # A long sequence pages through its frames: 150 frames, no worker: the strip shows a window of 60.
    stop(worker)
    status, body = client.call("POST", "/v1/jobs", {"frames": sequence_frames(150, 16, 16), "tile_size": 16,
                                                     "name": "browser-test long"})
    if status != 201:
        fail(f"submit of the long sequence answered {status}: {body}")
    long = body["id"]
    d.get(base + f"/#/jobs/{long}/frames")

    def window_is(a, b):
        states = cell_states(d)
        return sorted(states) == list(range(a, b + 1)) and d.find_element(By.ID, "frame-range").text == f"{a}–{b} of 150"
    wait_for("frames 1-60", lambda: window_is(1, 60))
    click(d, '[data-page="next"]', "the next page")
    wait_for("frames 61-120", lambda: window_is(61, 120))
    click(d, '[data-page="next"]', "the next page")
    wait_for("frames 121-150", lambda: window_is(121, 150))
    if d.find_element(By.CSS_SELECTOR, '[data-page="next"]').is_enabled():
        fail("the last page offers a next one")
    click(d, '[data-page="prev"]', "the previous page")
    wait_for("frames 61-120 again", lambda: window_is(61, 120))
    d.find_element(By.ID, "frame-goto").send_keys("140\n")
    wait_for("frame 140 chosen, its window around it", lambda: d.current_url.endswith(f"/jobs/{long}/frames/140")
             and window_is(91, 150) and selected_frame(d) == 140
             and d.find_element(By.ID, "job-title").text == "Frame 140")
    d.save_screenshot(os.path.join(ARTEFACTS, "monitor-sequence-paged.png"))
    client.call("DELETE", f"/v1/jobs/{long}")
    print("paging: 150 frames shown 60 at a time, frame 140 found by its number")
    return [retried]


def main():
    client_path, client_token = token_file("client.token")
    worker_path, worker_token = token_file("worker.token")
    ready = os.path.join(WORK, "ready")
    # Long leases: the held tiles stay leased for the whole test, whatever the machine's speed.
    serve = start([TESSERA, "serve", "--data", os.path.join(WORK, "data"), "--listen", "127.0.0.1:0",
                   "--ready-file", ready, "--lease-seconds", "600", "--tile-failure-workers", "1",
                   # Room for the first few done tiles' logs only: the job page counts the rest as not kept.
                   "--max-tile-log-bytes", "2048",
                   "--client-token-file", client_path,
                   "--worker-token-file", worker_path], "serve.log")
    wait_for("the coordinator", lambda: os.path.exists(ready) and open(ready).read().strip())
    base = "http://" + open(ready).read().strip()
    client, workerside = Http(base, client_token), Http(base, worker_token)
    caps = json.loads(urllib.request.urlopen(base + "/monitor/capabilities.json", timeout=30).read())
    ep = caps["endpoints"]
    print("endpoints on this coordinator:", ", ".join(k for k, v in ep.items() if v) or "none of the optional ones")

    # The page and its headers need no token; the API does.
    with urllib.request.urlopen(base + "/", timeout=30) as r:
        csp = r.headers["Content-Security-Policy"] or ""
        if "script-src 'self'" not in csp or "default-src 'none'" not in csp:
            fail("the monitor page has no strict Content-Security-Policy: " + csp)
        if not r.headers["Content-Type"].startswith("text/html"):
            fail("index has Content-Type " + r.headers["Content-Type"])

    status, body = client.call("POST", "/v1/jobs", {"scene": sphere_scene(), "assets": {}, "tile_size": TILE, "seed": 3,
                                                     "replicates": 2, "bvh": "median", "name": "browser-test spheres",
                                                     "layers": ["albedo", "normal", "depth", "object_id"]})
    if status != 201:
        fail(f"submit answered {status}: {body}")
    job = body["id"]

    # The scripted worker leases the job's first tiles and keeps them.
    status, reg = workerside.call("POST", "/v1/workers", {"name": "holder", "threads": 1})
    holder = reg["id"]
    workerside.worker_secret = reg["secret"]
    held = []
    for _ in range(HELD):
        status, lease = workerside.call("POST", f"/v1/workers/{holder}/lease")
        if status != 200:
            fail(f"holder lease answered {status}")
        held.append(lease["lease"])

    d = browser()
    try:
        d.get(base + "/")
        # Token: a wrong one is refused with a clear message, the right one lets the page work.
        wait_for("the token dialog", lambda: visible(d, "#token-dialog"))
        d.find_element(By.ID, "token-input").send_keys("not-the-client-token-0123456789")
        d.find_element(By.ID, "token-submit").click()
        msg = wait_for("the wrong-token message", lambda: visible(d, "#token-error") and d.find_element(By.ID, "token-error").text)
        if "refused" not in msg or "401" not in msg:
            fail("unclear wrong-token message: " + msg)
        d.find_element(By.ID, "token-input").send_keys(worker_token)
        d.find_element(By.ID, "token-submit").click()
        wait_for("the 403 message", lambda: "403" in d.find_element(By.ID, "token-error").text)
        print("wrong tokens:", msg, "|", d.find_element(By.ID, "token-error").text)
        expected = console_errors(d)  # the refused calls above are logged by the browser; nothing may follow them
        if any("401" not in e["message"] and "403" not in e["message"] for e in expected):
            fail(f"unexpected console errors: {expected}")
        d.find_element(By.ID, "token-input").send_keys(client_token)
        d.find_element(By.ID, "token-submit").click()
        wait_for("the token dialog to close", lambda: not visible(d, "#token-dialog"))
        if "client.token" in d.current_url or client_token in d.current_url:
            fail("the token appears in the URL")

        # The page's SSE parser (server/monitor/sse.js), fed a stream cut at every position.
        parsed = d.execute_async_script("""
            const done = arguments[arguments.length - 1];
            import('/monitor/sse.js').then(({ SseParser }) => {
              const text = 'retry: 1000\\n\\n: keep-alive\\n\\nid: r-1\\nevent: job\\ndata: {"id":"j"}\\n\\n' +
                           'id: r-2\\r\\nevent: tile_done\\r\\ndata: a\\r\\ndata: b\\r\\n\\r\\ndata: plain\\n\\n';
              const results = [];
              for (let cut = 0; cut <= text.length; cut++) {
                const got = [];
                const p = new SseParser((e) => got.push(e.id + '|' + e.type + '|' + e.data));
                p.feed(text.slice(0, cut));
                p.feed(text.slice(cut));
                results.push(got.join(' / '));
              }
              done(results);
            }, (e) => done(['error: ' + e]));""")
        want = 'r-1|job|{"id":"j"} / r-2|tile_done|a\nb / r-2|message|plain'
        bad = [(i, r) for i, r in enumerate(parsed) if r != want]
        if bad:
            fail(f"the page's SSE parser: {bad[:3]} (want {want!r})")
        print(f"SSE parser: {len(parsed)} split points parsed alike")

        # The figures' clock (server/monitor/format.js), on the page's clock set by hand: a started job's elapsed time
        # goes on from its status's arrival until it ends, its ETA follows, and its Mrays/s are the status's own.
        figures = d.execute_async_script("""
            const done = arguments[arguments.length - 1];
            import('/monitor/format.js').then(({ arrived, jobFigures }) => {
              const real = performance.now;
              let t = 1000;
              performance.now = () => t;
              const tiles = { total: 10, done: 2, leased: 1, pending: 7 };
              const job = (state, started) => arrived({ state, started_ms: started ? 1 : null, render_seconds: started ? 10 : 0,
                                                        rays: started ? 20e6 : 0, tiles: { ...tiles } });
              const running = job('running', true), paused = job('paused', true), ended = job('done', true);
              const queued = job('queued', false);
              t += 6000;
              const f = (j) => { const x = jobFigures(j); return [x.secs, x.eta, x.mrays]; };
              const out = { running: f(running), paused: f(paused), done: f(ended), queued: f(queued) };
              performance.now = real;
              done(out);
            }, (e) => done('error: ' + e));""")
        want = {"running": [16, 64, 2], "paused": [16, None, 2], "done": [10, 0, 2], "queued": [0, None, None]}
        if figures != want:
            fail(f"the job figures' clock: {figures} (want {want})")
        print("figures: elapsed time extrapolated from each status's arrival while the job's clock runs")

        # The job list shows the job, running (the holder's leases started it).
        row = f'tr[data-job="{job}"]'
        wait_for("state running in the list", lambda: any("running" in r.text for r in visible(d, row)))
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-jobs.png"))
        click(d, row, "the job row")
        wait_for("the tile map", lambda: len(d.find_elements(By.CSS_SELECTOR, "#tilemap .tile")) == TOTAL_TILES)
        wait_for("the held tiles leased by holder", lambda: len(
            [t for t in d.find_elements(By.CSS_SELECTOR, '#tilemap .tile[data-state="leased"]') if "holder" in t.get_attribute("title")]) == HELD)
        # The job's sampling settings, from its spec.
        sampling = d.find_element(By.ID, "fig-sampling").text
        if not all(w in sampling for w in ("fixed spp", "2 replicates", "BVH: median")):
            fail(f"the job's sampling settings are not shown: {sampling!r}")

        wait_for("the event stream open", lambda: d.find_element(By.TAG_NAME, "body").get_attribute("data-events-live") == "true")
        # A real worker renders everything else; the page follows tile by tile.
        worker = start([TESSERA, "worker", "--coordinator", base, "--token-file", worker_path, "--threads", "1",
                        "--name", "render-1", "--cache", os.path.join(WORK, "cache")], "worker.log")
        wait_for("the free tiles done (API)", lambda: client.call("GET", f"/v1/jobs/{job}")[1]["tiles"]["done"] == TOTAL_TILES - HELD)
        wait_for("the free tiles done on the map", lambda: tiles_in(d, "done") == TOTAL_TILES - HELD)
        if tiles_in(d, "leased") != HELD:
            fail("the held tiles are not shown leased")
        # The map was fed by the event stream, not only by polling.
        from_events = int(d.find_element(By.ID, "tilemap").get_attribute("data-event-tiles-done") or 0)
        received = int(d.find_element(By.TAG_NAME, "body").get_attribute("data-events") or 0)
        if from_events < 1 or received < from_events:
            fail(f"the tile map did not follow the event stream: {from_events} tiles done from {received} events")
        print(f"events: {received} received, {from_events} tiles turned done from them")
        wait_for("the partial preview", lambda: d.execute_script(
            "const i = document.getElementById('preview'); return !i.hidden && i.complete && i.naturalWidth === arguments[1] "
            "&& i.dataset.tilesDone === String(arguments[0]);", TOTAL_TILES - HELD, WIDTH))
        # No tile lands while the holder keeps its tiles, so the image that says it holds every tile done is the
        # coordinator's preview as it is now (a preview fetched while tiles landed is fetched again after them).
        same = preview_is_the_coordinators(d, job)
        if same is not True:
            fail(f"the page's preview, said to hold {TOTAL_TILES - HELD} tiles, is not the coordinator's preview ({same})")
        click(d, '#tilemap .tile[data-state="leased"]', "a leased tile")
        wait_for("the tile details", lambda: "holder" in d.find_element(By.ID, "tile-detail").text)
        click(d, '#tilemap .tile[data-state="done"]', "a done tile")
        # With the log lines the worker sent with its upload (what it said about the lease, up to "rendered in").
        wait_for("a done tile's details from GET /v1/jobs/{id}/tiles, with the worker that rendered it and its log",
                 lambda: all(w in d.find_element(By.ID, "tile-detail").text
                             for w in ("Attempts", "Render time", "Rays", "No failures", "Rendered by", "render-1 (w-",
                                       "leased window", "rendered in")))
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-job-mid-render.png"))
        d.execute_script("document.querySelector('#tile-detail .tile-log').scrollIntoView();")
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-tile-log.png"))
        d.execute_script("window.scrollTo(0, 0);")  # the job's buttons back from under the header

        click(d, '[data-action="pause"]', "the pause button")
        wait_for("paused", lambda: (lambda j: j.get("state") == "paused" or j.get("paused") is True)(client.call("GET", f"/v1/jobs/{job}")[1]))
        for lease in held:
            workerside.call("POST", f"/v1/leases/{lease}/release")
        status, _ = workerside.call("POST", f"/v1/workers/{holder}/lease")
        if status != 204:
            fail(f"a paused job handed out a lease ({status})")
        wait_for("released tiles pending on the map", lambda: tiles_in(d, "pending") == HELD)
        click(d, '[data-action="resume"]', "the resume button")
        print("pause: no lease while paused; resumed from the page")

        wait_for("job done on the page", lambda: "done" in d.find_element(By.ID, "job-state").text)
        wait_for("every tile done on the map", lambda: tiles_in(d, "done") == TOTAL_TILES)
        # The legend counts the done tiles whose logs the coordinator did not keep, as its tile list does.
        _, listed = client.call("GET", f"/v1/jobs/{job}/tiles")
        if not listed.get("logs_not_kept"):
            fail(f"no tile log went unkept under --max-tile-log-bytes 2048: {listed.get('logs_not_kept')}")
        click(d, '#tilemap .tile[data-state="done"]', "a done tile")
        unkept = f"{listed['logs_not_kept']} tile logs not kept"
        wait_for(f"the legend's '{unkept}'", lambda: [e.text for e in visible(d, "#logs-not-kept")] == [unkept])
        print(f"tile logs: {unkept}, shown in the legend")
        wait_for("the final preview", lambda: d.execute_script(
            "const i = document.getElementById('preview'); return i.complete && i.dataset.tilesDone === String(arguments[0]);",
            TOTAL_TILES))
        if preview_is_the_coordinators(d, job) is not True:
            fail("the finished job's preview is not the coordinator's")
        # The result downloaded from the page is the coordinator's EXR, byte for byte, named after the job.
        click(d, '[data-action="download"]', "the download button")
        saved = os.path.join(DOWNLOADS, "browser-test_spheres.exr")
        wait_for("the downloaded EXR", lambda: os.path.exists(saved) and "Download: " in d.find_element(By.ID, "action-msg").text)
        status, exr = client.call("GET", f"/v1/jobs/{job}/result.exr")
        if status != 200 or open(saved, "rb").read() != exr:
            fail(f"the downloaded file is not the job's result ({status}, {os.path.getsize(saved)} / {len(exr)} bytes)")
        print(f"download: {os.path.basename(saved)}, {len(exr)} bytes, the coordinator's result")
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-job-done.png"))

        # The layer selector lists the job's output layers; choosing one shows the coordinator's preview of it.
        options = d.execute_script(
            "return [...document.querySelectorAll('#preview-layer option')].map((o) => o.value);")
        if options != ["", "albedo", "normal", "depth", "object_id"]:
            fail(f"the layer selector offers {options}")
        for layer in ("normal", ""):
            d.execute_script("const s = document.getElementById('preview-layer'); s.value = arguments[0];"
                             "s.dispatchEvent(new Event('change'));", layer)
            wait_for(f"the preview of layer '{layer}'", lambda: d.execute_script(
                "const i = document.getElementById('preview'); return i.complete && i.dataset.layer === arguments[0];",
                layer))
            if preview_is_the_coordinators(d, job, layer) is not True:
                fail(f"the preview of layer '{layer}' is not the coordinator's")
            if layer:
                d.save_screenshot(os.path.join(ARTEFACTS, "monitor-layers.png"))
        print("layer selector: albedo, normal, depth, object_id; the normal layer's preview is the coordinator's")

        # Delete the finished job from its page (the button asks for a second click); another job stays listed.
        status, kept = client.call("POST", "/v1/jobs", {"scene": sphere_scene(), "assets": {}, "tile_size": TILE,
                                                        "seed": 4, "name": "browser-test kept"})
        if status != 201:
            fail(f"submit of the second job answered {status}: {kept}")
        click(d, '[data-action="delete"]', "the delete button")
        wait_for("the delete confirmation", lambda: "for good" in d.find_element(By.CSS_SELECTOR, '[data-action="delete"]').text)
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-job-delete-confirm.png"))
        click(d, '[data-action="delete"]', "the delete confirmation")
        wait_for("the job list", lambda: d.current_url.endswith("#/jobs") and visible(d, f'tr[data-job="{kept["id"]}"]'))
        wait_for("the deleted job gone from the list", lambda: not d.find_elements(By.CSS_SELECTOR, row))
        status, _ = client.call("GET", f"/v1/jobs/{job}")
        if status != 404:
            fail(f"the deleted job still answers {status}")
        if os.path.exists(os.path.join(WORK, "data", "jobs", job)):
            fail("the deleted job's result folder is left")
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-jobs-after-delete.png"))
        print("delete: the finished job is gone from the page and the API (404)")

        # Workers page: drain when the coordinator has it.
        d.get(base + "/#/workers")
        # Each worker's rate over the tiles it rendered, as the API's rays over render seconds (render-1 is idle
        # by now, so its figures stand still).
        def rate_shown_is_the_apis():
            w = next(w for w in client.call("GET", "/v1/workers")[1]["workers"] if w["name"] == "render-1")
            if not (w["rays"] > 0 and w["render_seconds"] > 0):
                return False
            v = w["rays"] / w["render_seconds"] / 1e6
            want = f"{v:.0f}" if v >= 100 else f"{v:.1f}"
            return d.find_element(By.CSS_SELECTOR, 'tr[data-name="render-1"] td.rate').text == want
        wait_for("render-1's Mrays/s as the API has it", rate_shown_is_the_apis)
        click(d, 'tr[data-name="render-1"] [data-action="drain"]', "the drain button")
        wait_for("the worker draining", lambda: "draining" in d.find_element(By.CSS_SELECTOR, 'tr[data-name="render-1"]').text)
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-workers.png"))
        print("drain: render-1 draining")

        # A job that fails part-way (the scripted worker reports a failure with log lines; --tile-failure-workers 1
        # fails the job at once): the tile details show the failure and its log lines, and Retry on the page renders
        # only the tiles that were not done.
        # Priority 100: the holder's lease request below must get a tile of this job even while an earlier step's job
        # still has pending tiles (leases go to the highest priority first).
        status, body = client.call("POST", "/v1/jobs", {"scene": sphere_scene(), "assets": {}, "tile_size": TILE,
                                                         "seed": 4, "priority": 100, "name": "browser-test failing"})
        failing = body["id"]
        status, lease = workerside.call("POST", f"/v1/workers/{holder}/lease")
        if status != 200 or lease["job"] != failing:
            fail(f"the holder did not get a tile of the failing job: {status} {lease}")
        log = ["render of tile %d: out of memory after 3 GiB" % lease["tile"], "scripted worker gives up"]
        workerside.call("POST", f"/v1/leases/{lease['lease']}/fail", {"error": "out of memory (scripted)", "log": log})
        if client.call("GET", f"/v1/jobs/{failing}")[1]["state"] != "failed":
            fail("the failing job did not fail")
        d.get(base + f"/#/jobs/{failing}")
        wait_for("the failing job's tile map", lambda: tiles_in(d, "failed") == 1)
        click(d, f'#tilemap .tile[data-index="{lease["tile"]}"]', "the failed tile")
        wait_for("the failure and its log lines in the tile details", lambda: all(
            w in d.find_element(By.ID, "tile-detail").text for w in ("out of memory (scripted)", log[0], log[1], "Attempts")))
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-tile-details.png"))
        for w in client.call("GET", "/v1/workers")[1]["workers"]:
            client.call("POST", f"/v1/workers/{w['id']}/undrain")
        click(d, '[data-action="retry"]', "the retry button")
        wait_for("the retried job done on the page", lambda: "done" in d.find_element(By.ID, "job-state").text)
        attempts = [t["attempts"] for t in client.call("GET", f"/v1/jobs/{failing}/tiles")[1]["tiles"]]
        if sorted(attempts) != [1] * (TOTAL_TILES - 1) + [2]:
            fail(f"retry leased tiles more than once besides the failed one: attempts {attempts}")
        print("retry from the page: the failed tile leased twice, every other tile once")
        # Every job ended before the sequences come (the scripted worker's leases must get their tiles).
        wait_for("every job done", lambda: all(j["state"] == "done" for j in client.call("GET", "/v1/jobs")[1]["jobs"]))
        stop(worker)

        deleted = [job] + check_sequences(d, base, client, workerside, holder, worker_path)

        # A poll of a job's page that was in flight when the job was deleted may have logged its 404 (of the job, its
        # frames or a frame's job); nothing else.
        gone = re.compile("/v1/jobs/(" + "|".join(map(re.escape, deleted)) + r")([ /?]|\.f\d)")
        errors = [e for e in console_errors(d) if not (gone.search(e["message"]) and "404" in e["message"])]
        if errors:
            fail(f"console errors: {errors}")
    except BaseException:
        report_failure(d)
        raise
    finally:
        d.quit()
    check_shared_farm()
    print("PASS: job listed, tiles done on the map, preview shown, result downloaded, tokens checked, job deleted; "
          "sequence listed, its frames shown, chosen, retried and paged; a shared farm's owners, tags and controls by "
          "role; screenshots in", ARTEFACTS)


def check_shared_farm():
    """A coordinator with a users file, seen by the user ben: who the page is signed in as, owners, "my jobs", a job
    waiting for a worker with tags, worker tags, and the controls ben's role allows (his own job's, not bea's, no
    drain)."""
    users = os.path.join(WORK, "users.json")
    tokens = {}
    for name, role in [("ben", "user"), ("bea", "user"), ("wk", "worker")]:
        out = subprocess.run([TESSERA, "users", "add", name, "--role", role, "--users", users],
                             capture_output=True, text=True, check=True)
        tokens[name] = out.stdout.strip().splitlines()[-1]
    ready = os.path.join(WORK, "ready-shared")
    start([TESSERA, "serve", "--data", os.path.join(WORK, "data-shared"), "--listen", "127.0.0.1:0",
           "--ready-file", ready, "--users", users], "serve-shared.log")
    wait_for("the shared coordinator", lambda: os.path.exists(ready) and open(ready).read().strip())
    base = "http://" + open(ready).read().strip()
    ben, bea, wk = Http(base, tokens["ben"]), Http(base, tokens["bea"]), Http(base, tokens["wk"])
    job = {"scene": sphere_scene(), "assets": {}, "tile_size": TILE}
    status, mine = ben.call("POST", "/v1/jobs", {**job, "name": "ben's lookdev"})
    status2, theirs = bea.call("POST", "/v1/jobs", {**job, "name": "bea's hero shot", "require": ["bigmem"]})
    if status != 201 or status2 != 201:
        fail(f"submissions to the shared farm answered {status} and {status2}")
    for name, tags in [("render-07", ["gpu", "site-a"]), ("render-12", ["site-a"])]:
        status, _ = wk.call("POST", "/v1/workers", {"name": name, "threads": 8, "tags": tags})
        if status != 201:
            fail(f"registering {name} answered {status}")
    d = browser()
    try:
        d.get(base + "/")
        wait_for("the token dialog", lambda: visible(d, "#token-dialog"))
        d.find_element(By.ID, "token-input").send_keys(tokens["ben"])
        d.find_element(By.ID, "token-submit").click()
        wait_for("the token dialog to close", lambda: not visible(d, "#token-dialog"))
        who = wait_for("who the page is signed in as", lambda: visible(d, "#whoami") and d.find_element(By.ID, "whoami").text)
        if who != "ben · user":
            fail("the top bar says " + who)
        row = lambda j: d.find_element(By.CSS_SELECTOR, f'tr[data-job="{j}"]')
        wait_for("both jobs listed", lambda: row(mine["id"]) and row(theirs["id"]))
        if row(theirs["id"]).find_element(By.CSS_SELECTOR, "td.owner").text != "bea":
            fail("bea's job does not show its owner")
        waiting = wait_for("the waiting reason", lambda: row(theirs["id"]).find_element(By.CSS_SELECTOR, ".waiting").text)
        if waiting != "waiting for a worker with tags bigmem":
            fail("bea's job says " + waiting)
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-shared-farm.png"))
        d.find_element(By.ID, "my-jobs").click()
        wait_for("only ben's job under my jobs",
                 lambda: len(d.find_elements(By.CSS_SELECTOR, "tr[data-job]")) == 1 and row(mine["id"]))
        d.find_element(By.ID, "my-jobs").click()
        # bea's job: ben may look, not pause; his own: he may.
        d.get(base + "/#/jobs/" + theirs["id"])
        pause = wait_for("the pause button", lambda: visible(d, '[data-action="pause"]'))[0]
        wait_for("pause disabled on bea's job", lambda: pause.get_attribute("disabled") is not None)
        if "Only its owner (bea)" not in pause.get_attribute("title"):
            fail("the disabled pause does not say why: " + pause.get_attribute("title"))
        d.get(base + "/#/jobs/" + mine["id"])
        wait_for("ben's job page", lambda: d.find_element(By.ID, "fig-owner").text == "ben")
        click(d, '[data-action="pause"]:not([disabled])', "pause on ben's own job")
        wait_for("ben's job paused", lambda: ben.call("GET", "/v1/jobs/" + mine["id"])[1]["state"] == "paused")
        # Workers: their tags; no drain for a user.
        d.get(base + "/#/workers")
        wait_for("the workers' tags", lambda: len(d.find_elements(By.CSS_SELECTOR, "#workers-table .tag")) == 3)
        # Looked up afresh on each poll: the table is redrawn as the workers' figures change.
        wait_for("every drain button disabled for a user", lambda: (lambda drains: bool(drains) and all(
            b.get_attribute("disabled") is not None for b in drains))(
                d.find_elements(By.CSS_SELECTOR, "#workers-table button")))
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-shared-workers.png"))
        errors = console_errors(d)
        if errors:
            fail(f"console errors on the shared farm: {errors}")
    except BaseException:
        report_failure(d)
        raise
    finally:
        d.quit()


try:
    main()
finally:
    for p in PROCS:
        stop(p)
    if os.environ.get("KEEP_WORK"):
        print("work folder kept:", WORK)
    else:
        shutil.rmtree(WORK, ignore_errors=True)
