#!/usr/bin/env python3
"""Chaos soak of a Tessera farm (docs/operations.md, "Sustained faults").

One coordinator (`tessera serve --data DIR`) and several workers, some of them behind a fault-injecting proxy
(fault_proxy.py), render many small jobs while a driver, every few seconds, SIGKILLs and restarts random workers and
the coordinator (same port, same data folder), SIGKILLs the coordinator while it writes a large blob the driver
uploads, freezes workers (SIGSTOP, SIGCONT a few seconds later) and asks workers to stop (SIGTERM, restarted later). The driver's choices come from one seeded generator (--seed, printed).
After --seconds of faults the driver stops injecting, brings everything back up and waits (at most --finish-seconds)
until every job is done. Then it checks the end state only, never how fast anything went:
- every submitted job exists, is done, and its result is bitwise identical to `tessera render` of the same scene,
  spp and seed (tests/exr_compare);
- every tile of every job is done with pixels (its row names bytes its job's pixel file holds), no tile was merged twice (coordinator logs) or
  acknowledged as accepted twice (worker logs), and a tile never logged as merged was acknowledged as a duplicate
  or uploaded without an answer (its merge was committed just before a coordinator kill; the worker may have been
  killed before its retry);
- no lease is live, and the data folder holds nothing orphaned: jobs/ holds exactly the jobs' folders with their
  result.exr, tmp/ is empty, no *.tmp file anywhere, every blob is referenced by a job or is one the driver uploaded.
- the faults met work in flight: a lease expired, the coordinator was killed while leases were live and while it wrote
  a blob, a proxied connection was reset or left half-open (each kind of fault is tried once early on; a run where a
  class still did not land is repeated with the next seed, up to --attempts runs);
- renders are at least one per tile and at most one per tile plus what the faults could cost (a stored tile is never
  rendered again).
Exit status 0 when every check passes, 1 otherwise; figures go to stdout and WORK/seed-S/summary.json.
"""
import argparse
import collections
import hashlib
import json
import os
import random
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

HERE = Path(__file__).resolve().parent


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tessera", required=True)
    p.add_argument("--exr-compare", required=True)
    p.add_argument("--course", help="the course scenes folder, scenes/course (adds a textured Cornell box job with assets)")
    p.add_argument("--seconds", type=float, default=75, help="how long faults are injected")
    p.add_argument("--jobs", type=int, default=8)
    p.add_argument("--workers", type=int, default=4)
    p.add_argument("--proxied", type=int, default=2, help="workers that reach the coordinator through a proxy")
    p.add_argument("--seed", type=int, default=18)
    p.add_argument("--attempts", type=int, default=3,
                   help="runs (seeds --seed, --seed + 1, ...) to land every fault class before failing")
    p.add_argument("--finish-seconds", type=float, default=900, help="deadline for the jobs after the faults stop")
    p.add_argument("--work", help="work folder (default: a new temporary one, removed when the soak passes)")
    p.add_argument("--keep", action="store_true", help="keep the work folder")
    return p.parse_args()


def log(msg):
    print(f"[soak {time.strftime('%H:%M:%S')}] {msg}", flush=True)


SPHERES = """{{"integrator": {{"type": "intersection_test", "spp": 4, "point_light_position": [0, 3, 3],
  "point_light_flux": [40, 40, 40]}},
 "film": {{"resolution": [{w}, {h}]}},
 "camera": {{"position": [0, 0.3, 4], "look_at": [0, 0, 0], "fov": 45}},
 "textures": {{"white": {{"type": "constant", "color": [0.8, 0.7, 0.6]}},
              "blue": {{"type": "constant", "color": [0.2, 0.3, 0.9]}}}},
 "materials": {{"m": {{"type": "diffuse", "texture_name": "white"}}, "b": {{"type": "diffuse", "texture_name": "blue"}},
               "glass": {{"type": "refraction", "eta": 1.5}}}},
 "objects": [{{"type": "sphere", "center": [-0.6, 0, 0], "radius": 0.7, "material_name": "m"}},
             {{"type": "sphere", "center": [0.7, 0, 0.3], "radius": 0.5, "material_name": "glass"}},
             {{"type": "sphere", "center": [0, -101, 0], "radius": 100, "material_name": "b"}}]}}
"""


class Farm:
    """The processes of the farm: their start, signals and restarts, each logged to its own file in WORK."""

    def __init__(self, args, work):
        self.args = args
        self.work = work
        self.data = work / "data"
        self.port = None
        self.serve = None
        self.serve_starts = 0
        self.workers = {}   # name -> Popen
        self.stopped = set()  # names of SIGSTOPped workers
        self.proxies = {}   # worker name -> (Popen, port)
        self.faults_off = work / "faults-off"
        self.driver_blobs = set()  # blobs the driver uploaded itself, referenced by no job

    def start_serve(self):
        ready = self.work / "ready"
        ready.unlink(missing_ok=True)
        listen = f"127.0.0.1:{self.port or 0}"
        for attempt in range(100):
            with open(self.work / "serve.log", "a") as out:
                out.write(f"=== soak: start {self.serve_starts + 1} on {listen}\n")
                out.flush()
                proc = subprocess.Popen([self.args.tessera, "serve", "--listen", listen, "--data", str(self.data),
                                         "--ready-file", str(ready), "--lease-seconds", "3", "--heartbeat-seconds", "1",
                                         "--threads", "2"], stdout=out, stderr=subprocess.STDOUT)
            while proc.poll() is None and not (ready.exists() and ready.read_text().strip()):
                time.sleep(0.02)
            if proc.poll() is None:
                break
            time.sleep(0.1 * (attempt + 1))  # the port may not be free yet
        else:
            raise RuntimeError("the coordinator did not start (serve.log)")
        self.serve = proc
        self.serve_starts += 1
        if self.port is None:
            self.port = int(ready.read_text().split()[0].rsplit(":", 1)[1])

    def url(self):
        return f"http://127.0.0.1:{self.port}"

    def start_proxy(self, name, seed):
        ready = self.work / f"proxy-{name}.ready"
        proc = subprocess.Popen([sys.executable, str(HERE / "fault_proxy.py"), "--target", f"127.0.0.1:{self.port}",
                                 "--seed", str(seed), "--ready-file", str(ready),
                                 "--stats-file", str(self.work / f"proxy-{name}.json"),
                                 "--faults-off", str(self.faults_off)],
                                stdout=open(self.work / f"proxy-{name}.log", "a"), stderr=subprocess.STDOUT)
        while not (ready.exists() and ready.read_text().strip()):
            if proc.poll() is not None:
                raise RuntimeError(f"proxy {name} exited with {proc.returncode}")
            time.sleep(0.02)
        self.proxies[name] = (proc, int(ready.read_text()))

    def start_worker(self, name):
        port = self.proxies[name][1] if name in self.proxies else self.port
        with open(self.work / f"{name}.log", "a") as out:
            out.write("=== soak: start\n")
            out.flush()
            self.workers[name] = subprocess.Popen(
                [self.args.tessera, "worker", "--coordinator", f"http://127.0.0.1:{port}",
                 "--cache", str(self.work / f"cache-{name}"), "--name", name, "--threads", "2"],
                stdout=out, stderr=subprocess.STDOUT)
        self.stopped.discard(name)

    def running_workers(self):
        return [n for n, p in self.workers.items() if p.poll() is None and n not in self.stopped]

    def signal_worker(self, name, sig):
        self.workers[name].send_signal(sig)
        if sig == signal.SIGSTOP:
            self.stopped.add(name)
        elif sig == signal.SIGCONT:
            self.stopped.discard(name)
        elif sig == signal.SIGKILL:
            self.workers[name].wait()
            self.stopped.discard(name)

    def stop_all(self):
        """SIGCONT and SIGTERM every worker, then the coordinator, then the proxies; returns serve's exit status."""
        for n, p in self.workers.items():
            if p.poll() is None:
                p.send_signal(signal.SIGCONT)
                p.send_signal(signal.SIGTERM)
        for p in self.workers.values():
            try:
                p.wait(timeout=120)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        rc = None
        if self.serve and self.serve.poll() is None:
            self.serve.send_signal(signal.SIGTERM)
            try:
                rc = self.serve.wait(timeout=120)
            except subprocess.TimeoutExpired:
                self.serve.kill()
                rc = self.serve.wait()
        for p, _ in self.proxies.values():
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
        return rc

    def kill_everything(self):
        for p in list(self.workers.values()) + [q for q, _ in self.proxies.values()] + [self.serve]:
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGCONT)
                p.kill()
                p.wait()


def scaled_spp(n):
    """n times TESSERA_TEST_SPP_SCALE (N or 1/N, default 1; docs/testing.md), at least 1."""
    num, _, den = os.environ.get("TESSERA_TEST_SPP_SCALE", "1").partition("/")
    return max(1, n * int(num) // int(den or 1))


def make_jobs(args, work, rng):
    """Scenes and the jobs' parameters (scene, spp, seed, tile, name); the same for a given --seed."""
    scenes = {}  # name -> (scene file, width, height, spp choices)
    for w, h in ((48, 32), (40, 40)):
        path = work / f"spheres-{w}x{h}.json"
        path.write_text(SPHERES.format(w=w, h=h))
        scenes[path.stem] = (path, w, h, (1024, 2048, 4096))
    if args.course:  # the textured Cornell box (OBJ and EXR assets, uploaded as blobs), renders a tile in ~0.1-1 s
        src = Path(args.course)
        base = json.loads((src / "cbox_refract_textured.json").read_text())
        for w, h in ((32, 32), (48, 48), (64, 40)):
            box = work / f"cbox-{w}x{h}"
            box.mkdir()
            shutil.copytree(src / "assets", box / "assets")
            base["film"]["resolution"] = [w, h]
            (box / "scene.json").write_text(json.dumps(base))
            scenes[box.name] = (box / "scene.json", w, h, (1024, 2048, 4096))
    jobs = []
    names = sorted(scenes)
    for i in range(args.jobs):
        key = names[i % len(names)] if i < len(names) else rng.choice(names)
        path, w, h, spps = scenes[key]
        spp = scaled_spp(rng.choice(spps))
        seed = rng.randrange(0, 1000)
        tile = rng.choice((8, 16))
        tiles = -(-w // tile) * -(-h // tile)
        jobs.append(dict(name=f"soak-{i:03d}", scene=str(path), spp=spp, seed=seed, tile=tile, tiles=tiles))
    return jobs


def render_references(args, work, jobs):
    refs = {}
    for j in jobs:
        key = (j["scene"], j["spp"], j["seed"])
        if key in refs:
            j["ref"] = refs[key]
            continue
        out = work / f"ref-{len(refs)}.exr"
        subprocess.run([args.tessera, "render", j["scene"], "-o", str(out), "--spp", str(j["spp"]), "--seed",
                        str(j["seed"]), "-q"], check=True, stdout=subprocess.DEVNULL)
        refs[key] = str(out)
        j["ref"] = str(out)


class Submitter(threading.Thread):
    """Submits the jobs one after another, spread over most of the fault phase, retrying each until the
    coordinator answers (a submission whose answer was lost to a kill may exist twice: both are checked)."""

    def __init__(self, farm, jobs, spread):
        super().__init__(daemon=True)
        self.farm, self.jobs, self.spread = farm, jobs, spread
        self.attempts = 0
        self.failed_attempts = 0
        self.error = None

    def run(self):
        try:
            for i, j in enumerate(self.jobs):
                while True:
                    self.attempts += 1
                    r = subprocess.run([self.farm.args.tessera, "submit", j["scene"], "--coordinator", self.farm.url(),
                                        "--spp", str(j["spp"]), "--seed", str(j["seed"]), "--tile", str(j["tile"]),
                                        "--name", j["name"], "--detach", "-q"],
                                       capture_output=True, text=True, timeout=120)
                    if r.returncode == 0:
                        break
                    self.failed_attempts += 1
                    time.sleep(0.5)
                time.sleep(self.spread / max(1, len(self.jobs)))
        except Exception as e:  # noqa: BLE001 (reported by the driver)
            self.error = repr(e)


def get_jobs(url):
    with urllib.request.urlopen(url + "/v1/jobs", timeout=10) as r:
        return json.load(r)["jobs"]


def live_leases(url):
    """The coordinator's live leases (its /metrics gauge), or None when it does not answer."""
    try:
        with urllib.request.urlopen(url + "/metrics", timeout=5) as r:
            m = re.search(r"^tessera_leases (\d+)$", r.read().decode(), re.M)
            return int(m.group(1)) if m else None
    except OSError:
        return None


def put_blob(url, sha, data):
    try:
        req = urllib.request.Request(f"{url}/v1/blobs/{sha}", data=data, method="PUT")
        urllib.request.urlopen(req, timeout=60).close()
    except OSError:
        pass  # the kill this upload was made for


def kill_in_blob_write(farm):
    """SIGKILLs the coordinator while it writes a large blob (its temp file exists, not yet renamed into place);
    returns False when the write finished before the driver saw the temp file."""
    data = os.urandom(48 << 20)
    sha = hashlib.sha256(data).hexdigest()
    farm.driver_blobs.add(sha)
    upload = threading.Thread(target=put_blob, args=(farm.url(), sha, data), daemon=True)
    upload.start()
    folder = farm.data / "blobs" / sha[:2]
    while upload.is_alive():
        if folder.is_dir() and any(folder.glob(sha + ".*.tmp")):
            farm.serve.kill()
            farm.serve.wait()
            upload.join()
            return True
        time.sleep(0.001)
    return False


FAULT_KINDS = ["kill_worker", "stop_worker", "kill_coordinator", "term_worker", "kill_coordinator_in_blob_write"]


def inject_faults(args, farm, rng, counts):
    """The fault phase: every 1-4 s one fault; SIGCONTs and restarts follow after their own random delays."""
    pending = []  # (due time, what, name)
    end = time.monotonic() + args.seconds
    next_fault = time.monotonic() + rng.uniform(1, 4)
    names = sorted(farm.workers)
    first = list(FAULT_KINDS)
    rng.shuffle(first)

    def due(events, now):
        keep = []
        for t, what, name in events:
            if t > now:
                keep.append((t, what, name))
            elif what == "cont":
                farm.signal_worker(name, signal.SIGCONT)
            elif what == "restart_worker":
                farm.start_worker(name)
            elif what == "restart_serve":
                farm.start_serve()
        return keep

    while time.monotonic() < end:
        now = time.monotonic()
        pending = due(pending, now)
        # A worker that exited by itself (e.g. after SIGTERM) is started again, as a supervisor would.
        for n in names:
            if farm.workers[n].poll() is not None and not any(x[2] == n for x in pending):
                pending.append((now + rng.uniform(0.2, 2), "restart_worker", n))
        if now >= next_fault:
            next_fault = now + rng.uniform(1, 4)
            # Each kind of fault once first, in a seeded order, so every class the end checks demand is tried
            # early; then at random.
            kind = first.pop() if first else rng.choices(FAULT_KINDS, [3, 3, 2, 1, 2])[0]
            live = farm.running_workers()
            if kind == "kill_coordinator_in_blob_write":
                if farm.serve.poll() is None:
                    counts[kind if kill_in_blob_write(farm) else "blob_write_finished_before_kill"] += 1
                    if farm.serve.poll() is not None:
                        pending.append((now + rng.uniform(0.2, 3), "restart_serve", "serve"))
            elif kind == "kill_coordinator":
                if farm.serve.poll() is None:
                    if (live_leases(farm.url()) or 0) > 0:
                        counts["kill_coordinator_with_live_leases"] += 1
                    farm.serve.kill()
                    farm.serve.wait()
                    counts[kind] += 1
                    pending.append((now + rng.uniform(0.2, 3), "restart_serve", "serve"))
            elif live:
                name = rng.choice(live)
                if kind == "kill_worker":
                    farm.signal_worker(name, signal.SIGKILL)
                    pending.append((now + rng.uniform(0.2, 2), "restart_worker", name))
                elif kind == "stop_worker":
                    farm.signal_worker(name, signal.SIGSTOP)
                    # Some freezes outlast the 3 s lease (it expires), some do not.
                    pending.append((now + rng.uniform(0.5, 8), "cont", name))
                else:
                    farm.signal_worker(name, signal.SIGTERM)  # restarted once it has exited (see above)
                counts[kind] += 1
        time.sleep(0.05)
    # The faults stop: everything due is done now, and the farm is whole again.
    farm.faults_off.touch()
    due(pending, float("inf"))
    if farm.serve.poll() is not None:
        farm.start_serve()
    for n in names:
        if n in farm.stopped:
            farm.signal_worker(n, signal.SIGCONT)
        if farm.workers[n].poll() is not None:
            farm.start_worker(n)


def wait_until_done(args, farm, submitter, jobs):
    deadline = time.monotonic() + args.finish_seconds
    names = {j["name"] for j in jobs}
    last = ""
    while time.monotonic() < deadline:
        # Workers that exit on their own (a SIGTERM that arrived just before the faults stopped) are restarted.
        for n, p in farm.workers.items():
            if p.poll() is not None:
                farm.start_worker(n)
        try:
            listed = get_jobs(farm.url())
        except OSError:
            listed = None
        if listed is not None and not submitter.is_alive():
            states = collections.Counter(j["state"] for j in listed)
            seen = {j["name"] for j in listed}
            status = ", ".join(f"{k} {v}" for k, v in sorted(states.items()))
            if status != last:
                log(f"jobs: {status}")
                last = status
            if names <= seen and all(j["state"] in ("done", "failed", "cancelled") for j in listed):
                return True
        time.sleep(0.5)
    return False


def check_end_state(args, farm, jobs, submitter, faults, proxy):
    """Every check of the module docstring; returns (problems, figures)."""
    problems = []
    db = sqlite3.connect(f"file:{farm.data / 'tessera.db'}?mode=ro", uri=True)
    rows = db.execute("SELECT id, name, state, width, height, tile_size, spp, seed, error FROM jobs").fetchall()
    by_name = {j["name"]: j for j in jobs}
    ids = set()
    per_name = collections.Counter()
    for jid, name, state, w, h, tile, spp, seed, error in rows:
        ids.add(jid)
        per_name[name] += 1
        j = by_name.get(name)
        if j is None:
            problems.append(f"job {jid} '{name}' was never submitted by the soak")
            continue
        if state != "done":
            problems.append(f"job {jid} ({name}) ended {state}: {error}")
            continue
        if (spp, seed, tile) != (j["spp"], j["seed"], j["tile"]):
            problems.append(f"job {jid} ({name}) has spp/seed/tile {spp}/{seed}/{tile}, submitted {j['spp']}/"
                            f"{j['seed']}/{j['tile']}")
        n, done, end = db.execute(
            "SELECT count(*), sum(state = 'done' AND (pixels IS NOT NULL OR pixel_length IS NOT NULL)),"
            " max(pixel_offset + pixel_length) FROM tiles WHERE job = ?", (jid,)).fetchone()
        if n != j["tiles"] or done != j["tiles"]:
            problems.append(f"job {jid} ({name}): {done} of {n} tiles done with pixels, expected {j['tiles']}")
        pixel_file = farm.data / "pixels" / f"{jid}.pixels"
        if end is not None and (not pixel_file.exists() or pixel_file.stat().st_size < end):
            problems.append(f"job {jid} ({name}): {pixel_file} does not hold the {end} bytes its tiles name")
        result = farm.data / "jobs" / jid / "result.exr"
        r = subprocess.run([args.exr_compare, j["ref"], str(result)], capture_output=True, text=True)
        if r.returncode != 0:
            problems.append(f"job {jid} ({name}): result differs from the single-process render: "
                            f"{(r.stdout + r.stderr).strip()[:300]}")
    for name in by_name:
        if per_name[name] == 0:
            problems.append(f"submitted job {name} is not in the database")
    twice = sorted(n for n, c in per_name.items() if c > 1)
    live = db.execute("SELECT count(*) FROM leases WHERE state = 'live'").fetchone()[0]
    if live:
        problems.append(f"{live} lease(s) still live after every job ended")
    lease_states = dict(db.execute("SELECT state, count(*) FROM leases GROUP BY state").fetchall())
    tiles_total = db.execute("SELECT count(*) FROM tiles").fetchone()[0]
    blobs_used = set()
    for (jid, record) in db.execute("SELECT id, record FROM job_records").fetchall():
        blobs_used.update(re.findall(r"[0-9a-f]{64}", record))
    for (h,) in db.execute("SELECT scene_hash FROM jobs"):
        blobs_used.add(h)
    db.close()

    # Logs: no tile merged or accepted twice; a tile never logged as merged was acknowledged as a duplicate.
    serve_log = (farm.work / "serve.log").read_text(errors="replace")
    merged = collections.Counter(re.findall(r"job (\S+) tile (\d+) worker \S+: merged", serve_log))
    accepted, duplicate = collections.Counter(), collections.Counter()
    unanswered = set()  # (job, tile) of uploads that got no answer: the coordinator may have stored them and died
    renders = 0
    for name in farm.workers:
        text = (farm.work / f"{name}.log").read_text(errors="replace")
        renders += len(re.findall(r": rendered in", text))
        for job, tile, what in re.findall(r"job=(\S+) tile=(\d+) lease=\S+: upload (accepted|duplicate)", text):
            (accepted if what == "accepted" else duplicate)[(job, tile)] += 1
        unanswered.update(re.findall(r"job=(\S+) tile=(\d+) lease=\S+: upload attempt \d+ failed", text))
    leftovers = sum(int(n) for n in re.findall(r"removed (\d+) temporary file", serve_log))
    tiles_done_before_restart = set(re.findall(r"job (\S+): every tile was done before the restart", serve_log))
    unlogged = 0
    for jid, _, state, w, h, tile, *_ in rows:
        for idx in range(-(-w // tile) * -(-h // tile)):
            key = (jid, str(idx))
            if merged[key] > 1:
                problems.append(f"job {jid} tile {idx} merged {merged[key]} times")
            if accepted[key] > 1:
                problems.append(f"job {jid} tile {idx} acknowledged as accepted {accepted[key]} times")
            if merged[key] == 0:
                unlogged += 1
                if duplicate[key] == 0 and key not in unanswered and jid not in tiles_done_before_restart:
                    problems.append(f"job {jid} tile {idx} is done but was neither logged as merged, nor "
                                    "acknowledged as a duplicate, nor uploaded without an answer")

    # The data folder: nothing orphaned.
    jobs_dir = farm.data / "jobs"
    dirs = {p.name for p in jobs_dir.iterdir()} if jobs_dir.exists() else set()
    for extra in sorted(dirs - ids):
        problems.append(f"orphaned job folder {jobs_dir / extra}")
    for jid in sorted(ids & dirs):
        extra = sorted(p.name for p in (jobs_dir / jid).iterdir() if p.name != "result.exr")
        if extra:
            problems.append(f"stray files in {jobs_dir / jid}: {extra}")
    tmp = farm.data / "tmp"
    if tmp.exists() and any(tmp.iterdir()):
        problems.append(f"{tmp} is not empty: {sorted(p.name for p in tmp.iterdir())[:10]}")
    for p in farm.data.rglob("*.tmp"):
        problems.append(f"temporary file left behind: {p}")
    blobs = farm.data / "blobs"
    for p in (blobs.rglob("*") if blobs.exists() else []):
        if p.is_file() and p.suffix != ".tmp" and p.name not in blobs_used | farm.driver_blobs:
            problems.append(f"orphaned blob {p}")
    pixels = farm.data / "pixels"
    for p in (pixels.iterdir() if pixels.exists() else []):
        if p.suffix != ".pixels" or p.stem not in ids:
            problems.append(f"orphaned pixel file {p}")
    for p in farm.data.iterdir():
        if p.name not in ("jobs", "tmp", "blobs", "pixels", "tessera.db", "tessera.db-wal", "tessera.db-shm"):
            problems.append(f"unexpected entry in the data folder: {p}")

    # Every render is one lease's; a stored tile is never rendered again, so renders beyond one per tile are bounded
    # by what the faults could cost: a worker killed, frozen past its lease or stopped loses at most the tile it
    # renders, the one it leased ahead and the upload in flight; a coordinator kill at most one per worker; a proxied
    # connection reset or left half-open at most one.
    if renders < tiles_total:
        problems.append(f"{renders} renders for {tiles_total} tiles: the worker logs miss renders")
    allowance = (3 * (faults.get("kill_worker", 0) + faults.get("stop_worker", 0) + faults.get("term_worker", 0))
                 + args.workers * (faults.get("kill_coordinator", 0) + faults.get("kill_coordinator_in_blob_write", 0))
                 + proxy.get("reset", 0) + proxy.get("half_open", 0))
    if renders > tiles_total + allowance:
        problems.append(f"{renders} renders for {tiles_total} tiles: more than the {allowance} the faults allow "
                        "(stored tiles rendered again?)")

    figures = dict(jobs_submitted=len(jobs), jobs_in_database=len(rows), submitted_twice=twice,
                   tiles=tiles_total, tile_renders=renders, uploads_accepted=sum(accepted.values()),
                   uploads_duplicate=sum(duplicate.values()), merges_not_logged=unlogged, temp_files_removed_at_restart=leftovers, lease_states=lease_states,
                   submit_attempts=submitter.attempts, submit_failed_attempts=submitter.failed_attempts)
    return problems, figures


def faults_missed(counts, proxy, lease_states, proxied):
    """The fault classes the soak exists to exercise that did not land on work in flight in this run."""
    missed = []
    if lease_states.get("expired", 0) == 0:
        missed.append("no lease expired")
    if counts["kill_coordinator_with_live_leases"] == 0:
        missed.append("no coordinator kill while leases were live")
    if counts["kill_coordinator_in_blob_write"] == 0:
        missed.append("no coordinator kill during a blob write")
    if proxied and proxy.get("reset", 0) + proxy.get("half_open", 0) == 0:
        missed.append("no proxied connection reset or left half-open")
    return missed


def soak_once(args, seed, work):
    """One soak with one seed in WORK; returns (problems, fault classes missed)."""
    rng = random.Random(seed)
    log(f"seed {seed} (repeat with --seed {seed}); {args.seconds:.0f} s of faults, {args.jobs} jobs, "
        f"{args.workers} workers ({args.proxied} behind a fault proxy); work folder {work}")
    jobs = make_jobs(args, work, rng)
    render_references(args, work, jobs)
    log(f"{len(jobs)} jobs, {sum(j['tiles'] for j in jobs)} tiles; references rendered")

    farm = Farm(args, work)
    counts = collections.Counter({k: 0 for k in FAULT_KINDS + ["kill_coordinator_with_live_leases"]})
    problems, missed = ["the soak did not finish"], []
    t0 = time.monotonic()
    try:
        farm.start_serve()
        names = [f"w{i}" for i in range(args.workers)]
        for i, n in enumerate(names[: args.proxied]):
            farm.start_proxy(n, rng.randrange(1 << 30))
        for n in names:
            farm.start_worker(n)
        submitter = Submitter(farm, jobs, args.seconds * 0.8)
        submitter.start()
        inject_faults(args, farm, rng, counts)
        fault_minutes = (time.monotonic() - t0) / 60
        log(f"faults stopped after {fault_minutes:.1f} min: {dict(counts)}; waiting for the jobs")
        submitter.join(timeout=args.finish_seconds)
        finished = wait_until_done(args, farm, submitter, jobs)
        serve_rc = farm.stop_all()
        problems = []
        if submitter.error:
            problems.append(f"the submitter stopped: {submitter.error}")
        if not finished:
            problems.append(f"the jobs did not all end within {args.finish_seconds:.0f} s after the faults stopped")
        if serve_rc != 0:
            problems.append(f"the coordinator exited with {serve_rc} on SIGTERM")
        proxy = collections.Counter()
        for n in farm.proxies:
            f = work / f"proxy-{n}.json"
            if f.exists():
                proxy.update(json.loads(f.read_text()))
        more, figures = check_end_state(args, farm, jobs, submitter, counts, proxy)
        problems += more
        missed = faults_missed(counts, proxy, figures["lease_states"], args.proxied)
        figures.update(faults_missed=missed, seed=seed, fault_minutes=round(fault_minutes, 2),
                       total_minutes=round((time.monotonic() - t0) / 60, 2), faults=dict(counts),
                       coordinator_starts=farm.serve_starts, proxy_connections=dict(proxy), problems=problems)
        (work / "summary.json").write_text(json.dumps(figures, indent=1) + "\n")
        print(json.dumps(figures, indent=1))
        for p in problems:
            print(f"FAIL: {p}", file=sys.stderr)
        for m in missed:
            print(f"fault class missed: {m}", file=sys.stderr)
    finally:
        farm.kill_everything()
    return problems, missed


def main():
    args = parse_args()
    if args.proxied > args.workers:
        sys.exit("--proxied must not exceed --workers")
    root = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="tessera-soak."))
    # A run whose end state is wrong fails at once. A run that is right but in which a fault class never met work in
    # flight proves less than it claims: it is run again with the next seed, and the soak fails if no run of
    # --attempts lands every class.
    for attempt in range(args.attempts):
        seed = args.seed + attempt
        work = root / f"seed-{seed}"
        work.mkdir(parents=True, exist_ok=True)
        problems, missed = soak_once(args, seed, work)
        if problems:
            log(f"FAIL ({len(problems)} problems); logs in {work}; repeat with --seed {seed}")
            return 1
        if not missed:
            log(f"PASS with seed {seed}: every fault class landed")
            if not args.keep and not args.work:
                shutil.rmtree(root, ignore_errors=True)
            return 0
        log(f"seed {seed}: end state right, but {'; '.join(missed)}: again with seed {seed + 1}")
    log(f"FAIL: in {args.attempts} runs some fault class never landed; logs in {root}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
