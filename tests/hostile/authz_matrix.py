#!/usr/bin/env python3
"""The authorization matrix of a shared farm (docs/operations.md, "Running a shared farm").

A coordinator runs with a users file made by `tessera users add` (an admin, two users, a viewer, a worker). Every
control route is called by every role, on the caller's own job and on another user's, without a credential and with
an unknown one; each answer is checked (2xx, 401 or 403; a tile requeue on a job with no failed tile is 409 once
admitted), and a refused request changes nothing (the job, the workers and the listing are compared before and
after). Then: job requirements against worker tags through the lease route, the audit trail, and a user removed from
the users file losing its token at once on SIGHUP, its open event stream included.

Usage: authz_matrix.py TESSERA
"""
import http.client
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

TESSERA = sys.argv[1]
failures = []


def scene(size=8):
    return {"integrator": {"type": "intersection_test", "spp": 1, "point_light_position": [0, 3, 3],
                           "point_light_flux": [40, 40, 40]},
            "film": {"resolution": [size, size]},
            "camera": {"position": [0, 0.3, 4], "look_at": [0, 0, 0], "fov": 45},
            "textures": {"white": {"type": "constant", "color": [0.8, 0.7, 0.6]}},
            "materials": {"m": {"type": "diffuse", "texture_name": "white"}},
            "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.7, "material_name": "m"}]}


class Farm:
    def __init__(self, address):
        self.host, port = address.rsplit(":", 1)
        self.port = int(port)

    def call(self, method, path, token=None, body=None, headers=None):
        conn = http.client.HTTPConnection(self.host, self.port, timeout=30)
        h = dict(headers or {})
        if token:
            h["Authorization"] = "Bearer " + token
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            h["Content-Type"] = "application/json"
        conn.request(method, path, body=data, headers=h)
        r = conn.getresponse()
        text = r.read()
        conn.close()
        try:
            return r.status, json.loads(text) if text else None
        except ValueError:
            return r.status, text


def main():
    work = tempfile.mkdtemp(prefix="tessera-authz-")
    users = os.path.join(work, "users.json")
    tokens = {}
    for name, role in [("ana", "admin"), ("ben", "user"), ("bea", "user"), ("cy", "viewer"), ("wk", "worker")]:
        out = subprocess.run([TESSERA, "users", "add", name, "--role", role, "--users", users],
                             capture_output=True, text=True, check=True)
        tokens[name] = out.stdout.strip().splitlines()[-1]
    listed = subprocess.run([TESSERA, "users", "ls", "--users", users], capture_output=True, text=True, check=True).stdout
    if "ben" not in listed or tokens["ben"] in listed or tokens["ben"] in open(users).read():
        failures.append(f"users ls / the users file: {listed}")
    ready = os.path.join(work, "ready")
    log = open(os.path.join(work, "serve.log"), "w")
    serve = subprocess.Popen([TESSERA, "serve", "--listen", "127.0.0.1:0", "--data", os.path.join(work, "data"),
                              "--ready-file", ready, "--users", users], stdout=subprocess.DEVNULL, stderr=log)
    try:
        deadline = time.time() + 30
        while not (os.path.exists(ready) and open(ready).read().strip()):
            if serve.poll() is not None or time.time() > deadline:
                sys.exit("the coordinator did not start:\n" + open(os.path.join(work, "serve.log")).read())
            time.sleep(0.05)
        farm = Farm(open(ready).read().strip())
        exercise(farm, tokens, users, serve)
    finally:
        serve.send_signal(signal.SIGTERM)
        serve.wait(timeout=30)
    for t in tokens.values():
        if t in open(os.path.join(work, "serve.log")).read():
            failures.append("a token appears in the coordinator's log")
    if failures:
        print("\n".join(failures))
        print(f"logs kept in {work}")
        sys.exit(1)
    shutil.rmtree(work)
    print("PASS")


def submit(farm, token, **extra):
    status, body = farm.call("POST", "/v1/jobs", token, {"scene": scene(), "tile_size": 4, **extra})
    assert status == 201, (status, body)
    return body["id"]


def job_state(farm, admin, job):
    status, body = farm.call("GET", f"/v1/jobs/{job}", admin)
    if status == 404:
        return None
    return {k: body[k] for k in ("state", "priority", "tiles", "owner")}


# The job controls: (name, method, path, body, what the job must be first, the answer once admitted).
CONTROLS = [
    ("priority", "PATCH", "/v1/jobs/{id}", {"priority": 7}, "queued", 200),
    ("pause", "POST", "/v1/jobs/{id}/pause", None, "queued", 200),
    ("resume", "POST", "/v1/jobs/{id}/resume", None, "paused", 200),
    ("cancel", "DELETE", "/v1/jobs/{id}", None, "queued", 200),
    ("retry", "POST", "/v1/jobs/{id}/retry", None, "cancelled", 200),
    ("purge", "DELETE", "/v1/jobs/{id}?purge=true", None, "cancelled", 200),
    # A queued job's pending tile without failures: admitted, then refused by its state.
    ("requeue", "POST", "/v1/jobs/{id}/tiles/0/requeue", None, "queued", 409),
]
ROLES = {"ana": "admin", "ben": "user", "cy": "viewer", "wk": "worker"}


def exercise(farm, tokens, users_file, serve):
    admin = tokens["ana"]
    cells = 0
    for name, method, path, body, needs, admitted in CONTROLS:
        for caller in ["ana", "ben", "cy", "wk", None, "bogus"]:
            for own in (True, False):
                role = ROLES.get(caller)
                if own and role not in ("admin", "user"):
                    continue  # a viewer or a worker cannot own a job
                owner = caller if own else "bea"
                job = submit(farm, tokens[owner])
                if needs == "paused":
                    farm.call("POST", f"/v1/jobs/{job}/pause", tokens[owner])
                elif needs == "cancelled":
                    farm.call("DELETE", f"/v1/jobs/{job}", tokens[owner])
                token = tokens.get(caller) if caller != "bogus" else "x" * 48
                if caller is None or caller == "bogus":
                    want = 401
                elif role == "admin" or (role == "user" and own):
                    want = admitted
                else:
                    want = 403
                before = job_state(farm, admin, job)
                workers_before = farm.call("GET", "/v1/workers", admin)[1]
                status, answer = farm.call(method, path.format(id=job), token, body)
                cells += 1
                where = f"{method} {path} by {caller or 'no credential'} ({role}) on {'its own' if own else 'another'} job"
                if status != want:
                    failures.append(f"{where}: {status}, wanted {want}: {answer}")
                if want in (401, 403):
                    after = job_state(farm, admin, job)
                    if after != before or farm.call("GET", "/v1/workers", admin)[1] != workers_before:
                        failures.append(f"{where}: refused ({status}) but the farm changed: {before} -> {after}")
                    if want == 403 and role == "user" and "belongs to bea" not in json.dumps(answer):
                        failures.append(f"{where}: the 403 does not say whose job it is: {answer}")
    # The farm's own controls: admins only.
    status, reg = farm.call("POST", "/v1/workers", tokens["wk"], {"name": "w", "tags": ["gpu"]})
    assert status == 201, (status, reg)
    for caller in ["ana", "ben", "cy", "wk", None]:
        for action in ("drain", "undrain"):
            want = 200 if caller == "ana" else 401 if caller is None else 403
            status, answer = farm.call("POST", f"/v1/workers/{reg['id']}/{action}", tokens.get(caller))
            cells += 1
            if status != want:
                failures.append(f"POST /v1/workers/{{wid}}/{action} by {caller}: {status}, wanted {want}: {answer}")
        want = 200 if caller == "ana" else 401 if caller is None else 403
        status, _ = farm.call("GET", "/v1/audit", tokens.get(caller))
        cells += 1
        if status != want:
            failures.append(f"GET /v1/audit by {caller}: {status}, wanted {want}")
        # Submissions: users and admins; reads: every client role.
        want = 201 if caller in ("ana", "ben") else 401 if caller is None else 403
        status, _ = farm.call("POST", "/v1/jobs", tokens.get(caller), {"scene": scene(), "tile_size": 4})
        cells += 1
        if status != want:
            failures.append(f"POST /v1/jobs by {caller}: {status}, wanted {want}")
        want = 200 if caller in ("ana", "ben", "cy") else 401 if caller is None else 403
        status, _ = farm.call("GET", "/v1/jobs", tokens.get(caller))
        cells += 1
        if status != want:
            failures.append(f"GET /v1/jobs by {caller}: {status}, wanted {want}")
    print(f"{cells} cells of the authorization matrix checked")

    # Who am I, owners and the listing by owner.
    status, me = farm.call("GET", "/v1/me", tokens["ben"])
    if status != 200 or me["user"] != "ben" or me["role"] != "user" or me["controls"].get("pause") != "own" \
            or me["controls"].get("drain") != "none":
        failures.append(f"GET /v1/me as ben: {status} {me}")
    status, mine = farm.call("GET", "/v1/jobs?owner=ben", tokens["cy"])
    if status != 200 or not mine["jobs"] or any(j["owner"] != "ben" for j in mine["jobs"]):
        failures.append(f"GET /v1/jobs?owner=ben: {status}")

    # Requirements against tags: a job requiring bigmem waits, says so, and goes only to a worker with the tag.
    big = submit(farm, tokens["ben"], require=["bigmem"], priority=100)
    _, j = farm.call("GET", f"/v1/jobs/{big}", tokens["ben"])
    if j["waiting_for"] != "a worker with tags bigmem" or j["require"] != ["bigmem"]:
        failures.append(f"a job requiring bigmem with no such worker: {j}")
    status, small = farm.call("POST", "/v1/workers", tokens["wk"], {"name": "laptop", "tags": ["site-a"]})
    status, large = farm.call("POST", "/v1/workers", tokens["wk"], {"name": "server", "tags": ["bigmem", "site-a"]})
    _, j = farm.call("GET", f"/v1/jobs/{big}", tokens["ben"])
    if j["waiting_for"] is not None:
        failures.append(f"a job requiring bigmem still waits once a worker has the tag: {j}")
    got = farm.call("POST", f"/v1/workers/{small['id']}/lease", tokens["wk"], {},
                    {"X-Tessera-Worker-Secret": small["secret"]})
    if got[0] == 200 and got[1]["job"] == big:
        failures.append("a worker without the tag bigmem was leased a tile of a job requiring it")
    got = farm.call("POST", f"/v1/workers/{large['id']}/lease", tokens["wk"], {},
                    {"X-Tessera-Worker-Secret": large["secret"]})
    if got[0] != 200 or got[1]["job"] != big:
        failures.append(f"the worker with the tag bigmem was not leased the job requiring it: {got}")
    status, bad = farm.call("POST", "/v1/jobs", tokens["ben"], {"scene": scene(), "require": ["Big Mem"]})
    if status != 400 or "may contain only" not in bad["error"]:
        failures.append(f"a requirement that is no tag: {status} {bad}")

    # The audit trail: the refusals and the actions, with who and from where.
    _, trail = farm.call("GET", "/v1/audit?limit=10000", admin)
    entries = trail["entries"]
    if not any(e["user"] == "ben" and e["status"] == 403 and e["action"] == "POST /v1/jobs/{id}/pause" for e in entries):
        failures.append("the audit trail has no refused pause by ben")
    if not any(e["user"] == "ana" and e["action"] == "POST /v1/workers/{wid}/drain" and e["status"] == 200
               and e["address"] == "127.0.0.1" for e in entries):
        failures.append("the audit trail has no drain by ana from 127.0.0.1")
    _, bens = farm.call("GET", "/v1/audit?user=ben&limit=10000", admin)
    if not bens["entries"] or any(e["user"] != "ben" for e in bens["entries"]):
        failures.append("GET /v1/audit?user=ben lists other users' actions")

    # A removed user: its token stops working at SIGHUP, and its open event stream ends.
    sock = socket.create_connection((farm.host, farm.port), timeout=60)
    sock.sendall(f"GET /v1/events HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {tokens['cy']}\r\n\r\n".encode())
    head = sock.recv(4096).decode(errors="replace")
    if " 200 " not in head.splitlines()[0]:
        failures.append(f"cy's event stream did not open: {head!r}")
    subprocess.run([TESSERA, "users", "rm", "cy", "--users", users_file], check=True, capture_output=True)
    serve.send_signal(signal.SIGHUP)
    ended = False
    deadline = time.time() + 60
    while time.time() < deadline:
        chunk = sock.recv(4096)
        if not chunk or b"\r\n0\r\n\r\n" in chunk:
            ended = True
            break
    sock.close()
    if not ended:
        failures.append("cy's event stream did not end after cy was removed and the coordinator got SIGHUP")
    status, _ = farm.call("GET", "/v1/jobs", tokens["cy"])
    if status != 401:
        failures.append(f"cy's token still works after its removal: {status}")
    if farm.call("GET", "/v1/jobs", tokens["ben"])[0] != 200:
        failures.append("ben's token stopped working when cy was removed")


main()
