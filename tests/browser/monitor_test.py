#!/usr/bin/python3
"""The web monitor in headless Chromium against a real coordinator and worker (ctest label `browser`).

Usage: monitor_test.py TESSERA ARTEFACT_DIR

Timing is driven, never raced: a scripted worker ("holder", plain HTTP) leases tiles and holds them while a real
`tessera worker` renders the rest, so the job page is shown mid-render with known tile states however fast the
machine is; the holder then hands its tiles back and the job finishes. Every wait polls a state with a generous
overall deadline. Exits 77 (ctest SKIP_RETURN_CODE) when Chromium, chromedriver or Selenium is missing.
"""
import json
import os
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
    from selenium.common.exceptions import StaleElementReferenceException
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
    moment ago may be gone: a stale element counts as "not yet" and the predicate runs again on a fresh look-up."""
    end = time.monotonic() + deadline
    while True:
        try:
            value = predicate()
        except StaleElementReferenceException:
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


def preview_is_the_coordinators(d, job):
    """Whether the preview the page shows has the same pixels as the one the coordinator makes now."""
    return d.execute_async_script("""
        const [job, done] = arguments;
        const pixels = (img) => {
          const c = document.createElement('canvas');
          c.width = img.naturalWidth;
          c.height = img.naturalHeight;
          const g = c.getContext('2d');
          g.drawImage(img, 0, 0);
          return g.getImageData(0, 0, c.width, c.height).data;
        };
        import('/monitor/api.js').then(async (api) => {
          const url = await api.previewUrl(job);
          const now = new Image();
          await new Promise((resolve, reject) => { now.onload = resolve; now.onerror = reject; now.src = url; });
          const a = pixels(document.getElementById('preview')), b = pixels(now);
          URL.revokeObjectURL(url);
          done(a.length === b.length && a.every((v, i) => v === b[i]));
        }).catch((e) => done('error: ' + e));""", job)


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


def sphere_scene():
    """The farm tests' small analytic scene (tests/farm/common.sh, write_sphere_scene)."""
    path = os.path.join(WORK, "scene.json")
    subprocess.run(["bash", "-c", 'source "$1" - - -; write_sphere_scene "$2" "$3" "$4" 4', "bash", FARM_COMMON, path,
                    str(WIDTH), str(HEIGHT)], check=True)
    return json.load(open(path))


def main():
    client_path, client_token = token_file("client.token")
    worker_path, worker_token = token_file("worker.token")
    ready = os.path.join(WORK, "ready")
    # Long leases: the held tiles stay leased for the whole test, whatever the machine's speed.
    serve = start([TESSERA, "serve", "--data", os.path.join(WORK, "data"), "--listen", "127.0.0.1:0",
                   "--ready-file", ready, "--lease-seconds", "600", "--tile-failure-workers", "1",
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
                                                     "replicates": 2, "bvh": "median", "name": "browser-test spheres"})
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
        wait_for("a done tile's details from GET /v1/jobs/{id}/tiles, with the worker that rendered it", lambda: all(
            w in d.find_element(By.ID, "tile-detail").text
            for w in ("Attempts", "Render time", "Rays", "No failures", "Rendered by", "render-1 (w-")))
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-job-mid-render.png"))

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
        stop(worker)

        # A poll of the job page that was in flight when the job was deleted may have logged its 404; nothing else.
        errors = [e for e in console_errors(d) if not (f"/v1/jobs/{job} " in e["message"] and "404" in e["message"])]
        if errors:
            fail(f"console errors: {errors}")
    except BaseException:
        d.save_screenshot(os.path.join(ARTEFACTS, "monitor-failure.png"))
        print("page text at the failure:", d.find_element(By.TAG_NAME, "body").text[:2000])
        print("browser log:", d.get_log("browser"))
        raise
    finally:
        d.quit()
    print("PASS: job listed, tiles done on the map, preview shown, result downloaded, tokens checked, job deleted; screenshots in",
          ARTEFACTS)


try:
    main()
finally:
    for p in PROCS:
        stop(p)
    if os.environ.get("KEEP_WORK"):
        print("work folder kept:", WORK)
    else:
        shutil.rmtree(WORK, ignore_errors=True)
