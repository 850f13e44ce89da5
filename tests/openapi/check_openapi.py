#!/usr/bin/env python3
"""Starts a real coordinator, calls every endpoint of docs/openapi.yaml and validates each real answer (status,
content type, JSON body) against the document. Also checks that the document and the route table in
protocol/routes.cpp name the same paths and methods, so neither can drift (the monitor's /monitor/ paths are served
beside the route table and left out of that comparison).

usage: check_openapi.py TESSERA_BINARY SOURCE_DIR
"""
import hashlib
import http.client
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import yaml

TESSERA, SOURCE = sys.argv[1], sys.argv[2]
DOC = yaml.safe_load(open(os.path.join(SOURCE, "docs", "openapi.yaml")))
SCHEMAS = DOC["components"]["schemas"]
failures = []
covered = set()


# ---- a JSON-schema checker for the subset the document uses

def resolve(schema):
    while "$ref" in schema:
        ref = schema["$ref"]
        assert ref.startswith("#/components/"), ref
        node = DOC
        for part in ref[2:].split("/"):
            node = node[part]
        schema = node
    return schema


def check(value, schema, where):
    """Returns a list of problems (empty when value satisfies schema)."""
    schema = resolve(schema)
    problems = []
    if value is None:
        return [] if schema.get("nullable") else [f"{where}: null is not allowed"]
    for part in schema.get("allOf", []):
        problems += check(value, part, where)
    if "oneOf" in schema:
        matching = [part for part in schema["oneOf"] if not check(value, part, where)]
        if len(matching) != 1:
            return [f"{where}: matches {len(matching)} of the oneOf schemas, not 1"]
    t = schema.get("type")
    kinds = {"object": dict, "array": list, "string": str, "boolean": bool}
    if t in kinds and not isinstance(value, kinds[t]):
        return [f"{where}: expected {t}, got {type(value).__name__}"]
    if t == "integer" and (isinstance(value, bool) or not isinstance(value, int)):
        return [f"{where}: expected integer, got {value!r}"]
    if t == "number" and (isinstance(value, bool) or not isinstance(value, (int, float))):
        return [f"{where}: expected number, got {value!r}"]
    if "enum" in schema and value not in schema["enum"]:
        problems.append(f"{where}: {value!r} is not one of {schema['enum']}")
    if "minimum" in schema:
        if schema.get("exclusiveMinimum") and not value > schema["minimum"]:
            problems.append(f"{where}: {value} is not above {schema['minimum']}")
        elif value < schema["minimum"]:
            problems.append(f"{where}: {value} is below {schema['minimum']}")
    if "maximum" in schema and value > schema["maximum"]:
        problems.append(f"{where}: {value} is above {schema['maximum']}")
    if "minLength" in schema and len(value) < schema["minLength"]:
        problems.append(f"{where}: shorter than {schema['minLength']}")
    if "pattern" in schema and not re.search(schema["pattern"], value):
        problems.append(f"{where}: {value!r} does not match {schema['pattern']}")
    if isinstance(value, list):
        if len(value) < schema.get("minItems", 0) or len(value) > schema.get("maxItems", len(value)):
            problems.append(f"{where}: {len(value)} items")
        for i, item in enumerate(value):
            problems += check(item, schema.get("items", {}), f"{where}[{i}]")
    if isinstance(value, dict):
        props = schema.get("properties", {})
        for key in schema.get("required", []):
            if key not in value:
                problems.append(f"{where}: missing {key!r}")
        extra = schema.get("additionalProperties", True)
        for key, v in value.items():
            if key in props:
                problems += check(v, props[key], f"{where}.{key}")
            elif extra is False and "allOf" not in schema:
                problems.append(f"{where}: unexpected key {key!r}")
            elif isinstance(extra, dict):
                problems += check(v, extra, f"{where}.{key}")
    return problems


def self_test():
    """The checker itself must catch what it claims to catch."""
    job = {"$ref": "#/components/schemas/Lease"}
    good = {"lease": "l-1", "job": "j-1", "tile": 0, "window": [0, 0, 8, 8], "spp": 1, "seed": 0,
            "scene_hash": "x", "deadline_ms": 5}
    assert check(good, job, "lease") == []
    assert check({**good, "extra": 1}, job, "lease"), "extra key not caught"
    assert check({**good, "window": [0, 0, 8]}, job, "lease"), "short array not caught"
    assert check({**good, "tile": "0"}, job, "lease"), "wrong type not caught"
    assert check({k: v for k, v in good.items() if k != "job"}, job, "lease"), "missing key not caught"
    assert check({"status": "nope"}, {"$ref": "#/components/schemas/UploadStatus"}, "s"), "enum not caught"


# ---- the document against the route table

def route_table_agrees():
    src = open(os.path.join(SOURCE, "protocol", "routes.cpp")).read()
    table = {}
    # {Endpoint::e, "name", "pattern", R::resource, {{"METHOD", A::access, ...}, ...}}
    for pattern, methods in re.findall(r'\{Endpoint::\w+, "\w+", "([^"]+)", R::\w+,\s*\{((?:\{[^}]*\},?\s*)+)\}\}', src):
        table[pattern] = {m.lower() for m in re.findall(r'\{"([A-Z]+)"', methods)}
    documented = {p: {m for m in ops if m in ("get", "put", "post", "delete", "head", "patch")}
                  for p, ops in DOC["paths"].items() if not p.startswith("/monitor/")}
    if not table:
        failures.append("no routes found in protocol/routes.cpp")
    if table != documented:
        failures.append(f"route table and docs/openapi.yaml differ:\n  code: {table}\n  doc:  {documented}")


# ---- calling the coordinator

def template_of(path):
    """The document's path template that a concrete path instantiates."""
    path = path.split("?")[0]
    for template in DOC["paths"]:
        regex = "^" + re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(template)) + "$"
        if re.match(regex, path):
            return template
    return None


class Coordinator:
    def __init__(self, address):
        self.host, self.port = address.rsplit(":", 1)
        self.secrets = {}  # worker id -> the secret its registration returned
        self.holders = {}  # lease id -> the worker it was granted to

    def acting_as(self, path):
        """The worker a request to path acts as: the one it names, or the holder of the lease it names."""
        parts = path.split("?")[0].split("/")
        if len(parts) == 5 and parts[1:3] == ["v1", "workers"] and parts[4] == "lease":
            return parts[3]
        if len(parts) == 5 and parts[1:3] == ["v1", "leases"]:
            return self.holders.get(parts[3])
        return None

    def call(self, method, path, body=None, content_type="application/json", expect=None, secret=None, headers=None):
        """Sends a request (with these extra headers); one acting as a worker carries that worker's secret unless
        `secret` names another."""
        if isinstance(body, (dict, list)):
            body = json.dumps(body).encode()
        elif isinstance(body, str):
            body = body.encode()
        conn = http.client.HTTPConnection(self.host, int(self.port), timeout=30)
        headers = {**({"Content-Type": content_type} if body is not None else {}), **(headers or {})}
        worker = self.acting_as(path)
        if secret is None and worker in self.secrets:
            secret = self.secrets[worker]
        if secret is not None:
            headers["X-Tessera-Worker-Secret"] = secret
        conn.request(method, path, body=body, headers=headers)
        r = conn.getresponse()
        data = r.read()
        ctype = r.getheader("Content-Type", "")
        conn.close()
        self.validate(method, path, r.status, ctype, data)
        if expect is not None and r.status != expect:
            failures.append(f"{method} {path}: expected {expect}, got {r.status} {data[:200]!r}")
        answer = json.loads(data) if ctype.startswith("application/json") and data else data
        if method == "POST" and path == "/v1/workers" and r.status == 201:
            self.secrets[answer["id"]] = answer["secret"]
        if method == "POST" and worker is not None and path.endswith("/lease") and r.status == 200:
            self.holders[answer["lease"]] = worker
        if method == "PUT" and worker is not None and r.status == 200 and "next" in answer:
            self.holders[answer["next"]["lease"]] = worker  # the next lease the upload asked for
        return r.status, answer

    def validate(self, method, path, status, ctype, data):
        where = f"{method} {path} -> {status}"
        template = template_of(path)
        if template is None:
            failures.append(f"{where}: path not in docs/openapi.yaml")
            return
        op = DOC["paths"][template].get(method.lower())
        if op is None:
            failures.append(f"{where}: method not documented for {template}")
            return
        response = op["responses"].get(str(status))
        if response is None:
            failures.append(f"{where}: status not documented for {method} {template}")
            return
        covered.add((template, method.lower()))
        response = resolve(response)
        content = response.get("content")
        if not content or method == "HEAD":
            return
        media = next((m for m in content if ctype.startswith(m)), None)
        if media is None:
            failures.append(f"{where}: content type {ctype!r} not in {list(content)}")
            return
        if media == "application/json":
            problems = check(json.loads(data), content[media]["schema"], "body")
            failures.extend(f"{where}: {p}" for p in problems)


class EventStream:
    """GET /v1/events held open; next() returns its events (name, id, data) with each data validated against the
    schema x-events gives for its name."""

    def __init__(self, c):
        self.conn = http.client.HTTPConnection(c.host, int(c.port), timeout=30)
        self.conn.request("GET", "/v1/events", headers={"Accept": "text/event-stream"})
        self.r = self.conn.getresponse()
        c.validate("GET", "/v1/events", self.r.status, self.r.getheader("Content-Type", ""), b"")
        media = DOC["paths"]["/v1/events"]["get"]["responses"]["200"]["content"]["text/event-stream"]
        self.schemas = media["x-events"]
        if self.r.status != 200:
            failures.append(f"GET /v1/events: {self.r.status} {self.r.read()[:200]!r}")

    def next(self):
        fields = {}
        while True:
            line = self.r.readline()
            if not line:
                return None
            line = line.decode().rstrip("\n")
            if line == "":
                if "event" in fields:
                    break
                fields = {}
                continue
            if line.startswith(":"):
                continue
            key, _, value = line.partition(": ")
            fields[key] = value
        name, data = fields["event"], json.loads(fields.get("data", "null"))
        if name not in self.schemas:
            failures.append(f"GET /v1/events: event {name!r} is not in x-events")
        else:
            failures.extend(f"GET /v1/events: event {name}: {p}" for p in check(data, self.schemas[name], "data"))
        return name, fields.get("id"), data

    def close(self):
        self.conn.close()


def sphere_scene(size):
    return {
        "integrator": {"type": "intersection_test", "spp": 1, "point_light_position": [0, 3, 3],
                       "point_light_flux": [40, 40, 40]},
        "film": {"resolution": [size, size]},
        "camera": {"position": [0, 0.3, 4], "look_at": [0, 0, 0], "fov": 45},
        "textures": {"white": {"type": "constant", "color": [0.8, 0.7, 0.6]}},
        "materials": {"m": {"type": "diffuse", "texture_name": "white"}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.7, "material_name": "m"}],
    }


def exercise(c, tessera, workdir, address):
    events = EventStream(c)  # open from the start: every event below is validated when read at the end
    c.call("GET", "/healthz", expect=200)
    c.call("GET", "/metrics", expect=200)
    _, capabilities = c.call("GET", "/monitor/capabilities.json", expect=200)
    if capabilities["tokens_required"] or not capabilities["endpoints"].get("purge"):
        failures.append(f"GET /monitor/capabilities.json of a coordinator without tokens: {capabilities}")

    blob = b"an asset's bytes"
    sha = hashlib.sha256(blob).hexdigest()
    c.call("PUT", f"/v1/blobs/{sha}", blob, "application/octet-stream", expect=201)
    c.call("PUT", f"/v1/blobs/{sha}", blob, "application/octet-stream", expect=200)
    c.call("PUT", f"/v1/blobs/{'0' * 64}", blob, "application/octet-stream", expect=400)
    c.call("HEAD", f"/v1/blobs/{sha}", expect=200)
    c.call("HEAD", f"/v1/blobs/{'1' * 64}", expect=404)
    _, q = c.call("POST", "/v1/blobs", {"sha256": [sha, "1" * 64]}, expect=200)
    assert q["missing"] == ["1" * 64], q
    c.call("POST", "/v1/blobs", {"sha256": ["not a hash"]}, expect=400)
    c.call("GET", f"/v1/blobs/{sha}", expect=200)
    c.call("GET", f"/v1/blobs/{'1' * 64}", expect=404)

    job = {"scene": sphere_scene(16), "tile_size": 8, "name": "openapi", "seed": 1}
    c.call("POST", "/v1/jobs", {**job, "spps": 2}, expect=400)
    _, a = c.call("POST", "/v1/jobs", job, expect=201)
    a = a["id"]
    c.call("GET", "/v1/jobs", expect=200)
    _, mine = c.call("GET", "/v1/jobs?owner=local", expect=200)
    if [j["id"] for j in mine["jobs"]] != [a] or mine["jobs"][0]["owner"] != "local":
        failures.append(f"GET /v1/jobs?owner=local: not the job just submitted by the open coordinator's caller: {mine}")
    c.call("GET", "/v1/jobs?owner=", expect=400)
    _, me = c.call("GET", "/v1/me", expect=200)
    if me["user"] != "local" or me["role"] != "admin" or me["controls"].get("pause") != "any":
        failures.append(f"GET /v1/me on an open coordinator: {me}")
    _, trail = c.call("GET", "/v1/audit?limit=5", expect=200)
    if not trail["entries"] or trail["entries"][0]["action"] != "POST /v1/jobs" or trail["entries"][0]["target"] != a:
        failures.append(f"GET /v1/audit: the submission of {a} is not the newest entry: {trail}")
    c.call("GET", "/v1/audit?limit=0", expect=400)
    c.call("GET", f"/v1/jobs/{a}", expect=200)
    c.call("GET", "/v1/jobs/j-none", expect=404)
    c.call("GET", f"/v1/jobs/{a}/spec", expect=200)
    c.call("GET", "/v1/jobs/j-none/spec", expect=404)
    c.call("GET", f"/v1/jobs/{a}/preview.png", expect=200)
    c.call("GET", "/v1/jobs/j-none/preview.png", expect=404)
    c.call("GET", f"/v1/jobs/{a}/result.exr", expect=409)
    c.call("GET", "/v1/jobs/j-none/result.exr", expect=404)

    c.call("POST", "/v1/workers", {"name": "openapi", "threads": 1, "colour": "red"}, expect=400)
    _, w1 = c.call("POST", "/v1/workers", {"name": "openapi", "threads": 1, "version": "test"}, expect=201)
    _, w2 = c.call("POST", "/v1/workers", None, expect=201)
    _, drained = c.call("POST", f"/v1/workers/{w2['id']}/drain", expect=200)
    if drained["state"] != "draining":
        failures.append(f"drain: the worker is {drained['state']}")
    c.call("POST", f"/v1/workers/{w2['id']}/lease", expect=204)  # drained: no work even with tiles pending
    c.call("POST", f"/v1/workers/{w2['id']}/drain", {"x": 1}, expect=400)
    c.call("POST", "/v1/workers/w-none/drain", expect=404)
    _, undrained = c.call("POST", f"/v1/workers/{w2['id']}/undrain", expect=200)
    if undrained["state"] != "idle":
        failures.append(f"undrain: the worker is {undrained['state']}")
    c.call("POST", "/v1/workers/w-none/undrain", expect=404)
    c.call("POST", "/v1/workers/w-none/lease", expect=404)
    _, l1 = c.call("POST", f"/v1/workers/{w1['id']}/lease", expect=200)
    c.call("POST", f"/v1/leases/{l1['lease']}/heartbeat", {"rays": 10}, expect=200)
    # Every request on a lease is its worker's alone: another worker's secret, or none, is 403.
    for method, target, body in (("POST", "heartbeat", {"rays": 1}), ("POST", "fail", {"error": "not mine"}),
                                 ("POST", "release", None), ("PUT", "result", b"x"), ("GET", "state", None)):
        for secret in (w2["secret"], ""):
            c.call(method, f"/v1/leases/{l1['lease']}/{target}", body,
                   "image/x-exr" if target == "result" else "application/json", expect=403, secret=secret)
    c.call("POST", f"/v1/workers/{w1['id']}/lease", expect=403, secret=w2["secret"])
    _, listed = c.call("GET", "/v1/workers", expect=200)
    mine = [w for w in listed["workers"] if w["id"] == w1["id"]]
    if not mine or mine[0]["state"] != "rendering" or mine[0]["tile"] != l1["tile"] or mine[0]["threads"] != 1:
        failures.append(f"GET /v1/workers: {w1['id']} is not shown rendering tile {l1['tile']}: {mine}")
    c.call("POST", f"/v1/leases/{l1['lease']}/heartbeat", {"rays": -1}, expect=400)
    c.call("POST", "/v1/leases/l-none/heartbeat", expect=404)
    c.call("PUT", f"/v1/leases/{l1['lease']}/result", b"not an exr", "image/x-exr", expect=422)  # w1's 1st failure
    c.call("POST", f"/v1/leases/{l1['lease']}/heartbeat", expect=410)
    c.call("PUT", "/v1/leases/l-none/result", b"x", "image/x-exr", expect=404)
    c.call("POST", f"/v1/workers/{w1['id']}/lease", {"known_jobs": "all"}, expect=400)  # refused before a tile is taken (HttpTest checks)
    _, l2 = c.call("POST", f"/v1/workers/{w1['id']}/lease", {"known_jobs": []}, expect=200)
    assert "spec" in l2 and "spec" not in l1, "a lease asked for with known_jobs carries its job's spec, a bare one not"
    c.call("POST", f"/v1/leases/{l2['lease']}/fail", {"error": "x", "more": 1}, expect=400)
    c.call("POST", f"/v1/leases/{l2['lease']}/fail", {"error": "x", "log": "one line"}, expect=400)
    c.call("POST", f"/v1/leases/{l2['lease']}/fail", {"error": "openapi test", "log": ["a line", "another"]},
           expect=200)  # 2nd: blocklisted
    _, tiles = c.call("GET", f"/v1/jobs/{a}/tiles", expect=200)
    failed = tiles["tiles"][l2["tile"]]["failures"]
    if not failed or failed[0]["log"] != ["a line", "another"]:
        failures.append(f"GET /v1/jobs/{{id}}/tiles: tile {l2['tile']} does not show the reported failure: {failed}")
    c.call("GET", "/v1/jobs/j-none/tiles", expect=404)
    c.call("POST", f"/v1/jobs/{a}/tiles/{l2['tile']}/requeue", {"x": 1}, expect=400)
    c.call("POST", f"/v1/jobs/{a}/tiles/{l2['tile']}/requeue", expect=200)  # it failed: its failures are forgotten
    c.call("POST", f"/v1/jobs/{a}/tiles/{l2['tile']}/requeue", expect=409)  # pending, no failures
    c.call("POST", f"/v1/jobs/{a}/tiles/999/requeue", expect=404)
    c.call("POST", "/v1/jobs/j-none/tiles/0/requeue", expect=404)
    c.call("POST", "/v1/leases/l-none/fail", expect=404)
    c.call("POST", f"/v1/workers/{w1['id']}/lease", expect=204)
    _, l3 = c.call("POST", f"/v1/workers/{w2['id']}/lease", expect=200)
    c.call("POST", f"/v1/leases/{l3['lease']}/release", {"why": 1}, expect=400)
    c.call("POST", f"/v1/leases/{l3['lease']}/release", expect=200)
    c.call("POST", "/v1/leases/l-none/release", expect=404)
    c.call("DELETE", f"/v1/jobs/{a}", expect=200)
    c.call("DELETE", f"/v1/jobs/{a}", expect=409)
    c.call("DELETE", "/v1/jobs/j-none", expect=404)
    c.call("PATCH", f"/v1/jobs/{a}", {"priority": 1}, expect=409)  # cancelled
    c.call("POST", f"/v1/jobs/{a}/retry", {"x": 1}, expect=400)
    _, again = c.call("POST", f"/v1/jobs/{a}/retry", expect=200)
    if again["state"] not in ("queued", "running") or again["error"] is not None:
        failures.append(f"retry: the job is {again['state']} with error {again['error']!r}")
    c.call("POST", f"/v1/jobs/{a}/retry", expect=409)
    c.call("POST", "/v1/jobs/j-none/retry", expect=404)
    c.call("POST", f"/v1/jobs/{a}/resume", expect=409)  # not paused
    c.call("POST", f"/v1/jobs/{a}/pause", {"x": 1}, expect=400)
    _, paused = c.call("POST", f"/v1/jobs/{a}/pause", expect=200)
    if paused["state"] != "paused":
        failures.append(f"pause: the job is {paused['state']}")
    c.call("GET", f"/v1/jobs/{a}", expect=200)
    c.call("POST", f"/v1/jobs/{a}/pause", expect=409)
    c.call("POST", "/v1/jobs/j-none/pause", expect=404)
    _, resumed = c.call("POST", f"/v1/jobs/{a}/resume", expect=200)
    if resumed["state"] not in ("queued", "running"):
        failures.append(f"resume: the job is {resumed['state']}")
    c.call("POST", "/v1/jobs/j-none/resume", expect=404)
    _, patched = c.call("PATCH", f"/v1/jobs/{a}", {"priority": 7}, expect=200)
    if patched["priority"] != 7:
        failures.append(f"patch: the job's priority is {patched['priority']}")
    c.call("PATCH", f"/v1/jobs/{a}", {"priority": 1, "name": "x"}, expect=400)
    c.call("PATCH", f"/v1/jobs/{a}", {}, expect=400)
    c.call("PATCH", "/v1/jobs/j-none", {"priority": 1}, expect=404)
    c.call("PATCH", f"/v1/jobs/{a}", {"spp": 4}, expect=409)  # not submitted as resumable
    c.call("PATCH", f"/v1/jobs/{a}", {"spp": 0}, expect=400)
    c.call("DELETE", f"/v1/jobs/{a}", expect=200)
    c.call("PUT", f"/v1/leases/{l3['lease']}/result", b"x", "image/x-exr", expect=410)
    # A job submitted after the cancelled one (dependencies): blocked, saying why; refusals of the pipeline fields;
    # the (empty) webhook log.
    status, blocked = c.call("POST", "/v1/jobs", {**job, "after": [a]}, expect=201)
    if status == 201:
        _, shown = c.call("GET", f"/v1/jobs/{blocked['id']}", expect=200)
        if shown["state"] != "blocked" or shown.get("reason") != f"dependency {a} was cancelled":
            failures.append(f"a job submitted after the cancelled {a} is not blocked by it: {shown}")
        _, held = c.call("GET", f"/v1/jobs/{a}", expect=200)
        if held.get("dependents") != [blocked["id"]]:
            failures.append(f"{a} does not list {blocked['id']} as its dependent: {held}")
        c.call("DELETE", f"/v1/jobs/{a}?purge=true", expect=409)  # it holds the blocked job back
        c.call("DELETE", f"/v1/jobs/{blocked['id']}", expect=200)
        c.call("DELETE", f"/v1/jobs/{blocked['id']}?purge=true", expect=200)  # the listings below count the others
    c.call("POST", "/v1/jobs", {**job, "after": ["j-none"]}, expect=400)
    c.call("POST", "/v1/jobs", {**job, "notify": "http://127.0.0.1:9/x"}, expect=403)
    c.call("POST", "/v1/jobs", {**job, "then": ["movie"]}, expect=400)
    c.call("GET", f"/v1/jobs/{a}/outputs/preview.png", expect=404)  # no steps
    c.call("GET", "/v1/webhooks/deliveries", expect=200)

    # A resumable job a real worker renders: the done states, the result and an accepted upload.
    _, b = c.call("POST", "/v1/jobs", {**job, "resumable": True}, expect=201)
    b = b["id"]
    # w2 takes one of b's tiles and hands it back: the real worker renders it, and w2's upload on that lease is then a
    # duplicate (below), settled without its body being looked at.
    _, lb = c.call("POST", f"/v1/workers/{w2['id']}/lease", expect=200)
    c.call("POST", f"/v1/leases/{lb['lease']}/release", expect=200)
    worker = subprocess.Popen([tessera, "worker", "--coordinator", "http://" + address, "--threads", "1"],
                              stdout=subprocess.DEVNULL, stderr=open(os.path.join(workdir, "worker.log"), "w"))
    try:
        deadline = time.time() + 60
        state = None
        while time.time() < deadline:
            _, j = c.call("GET", f"/v1/jobs/{b}", expect=200)
            state = j["state"]
            if state in ("done", "failed", "cancelled"):
                break
            time.sleep(0.1)
        if state != "done":
            failures.append(f"job {b} ended {state}, not done")
        # A sequence of two frames, once b is done (the test's coordinator queues one job at a time).
        frames = [{"number": n, "scene": sphere_scene(16)} for n in (3, 1)]
        c.call("POST", "/v1/jobs", {"frames": frames, "scene": sphere_scene(16)}, expect=400)
        c.call("POST", "/v1/jobs", {"frames": frames + [frames[0]]}, expect=400)  # frame 3 twice
        c.call("POST", "/v1/jobs", {"frames": frames, "resumable": True}, expect=400)  # one-image jobs only
        c.call("POST", "/v1/jobs", {"frames": frames, "frame_order": "random"}, expect=400)
        c.call("POST", "/v1/jobs", {"scene": sphere_scene(16), "frame_order": "any"}, expect=400)
        _, sq = c.call("POST", "/v1/jobs", {"frames": frames, "tile_size": 8, "seed": 1, "frame_order": "any"},
                       expect=201)
        if "id" not in sq:
            raise SystemExit(f"the sequence was refused: {sq}; failures so far: {failures}")
        sq = sq["id"]
        while time.time() < deadline:
            _, j = c.call("GET", f"/v1/jobs/{sq}", expect=200)
            if j["state"] in ("done", "failed", "cancelled"):
                break
            time.sleep(0.1)
        sequence_done = j["state"] == "done" and j["frames"]["done"] == 2
        if not sequence_done:
            failures.append(f"sequence {sq} ended {j['state']} with {j.get('frames')}, not done")
    finally:
        worker.send_signal(signal.SIGTERM)
        worker.wait(timeout=30)
    status, exr = c.call("GET", f"/v1/jobs/{b}/result.exr", expect=200)
    if status == 200 and exr[:4] != b"\x76\x2f\x31\x01":
        failures.append("result.exr is not an OpenEXR file")
    c.call("GET", f"/v1/jobs/{b}/preview.png", expect=200)
    _, listed = c.call("GET", "/v1/jobs", expect=200)
    listed = [j["id"] for j in listed["jobs"]]
    if sq not in listed or any(i.startswith(f"{sq}.") for i in listed):
        failures.append(f"GET /v1/jobs: the sequence {sq} is not listed as one job without its frames: {listed}")
    _, f3 = c.call("GET", f"/v1/jobs/{sq}.f3", expect=200)
    if f3.get("sequence") != sq or f3.get("frame") != 3 or "frames" in f3:
        failures.append(f"GET /v1/jobs/{sq}.f3: not frame 3 of {sq}: {f3}")
    c.call("GET", f"/v1/jobs/{sq}/preview.png", expect=200)  # its latest done frame's
    c.call("GET", f"/v1/jobs/{sq}/tiles", expect=409)  # its tiles are its frames'
    c.call("POST", f"/v1/jobs/{sq}/tiles/0/requeue", expect=409)
    c.call("PATCH", f"/v1/jobs/{sq}.f1", {"priority": 2}, expect=409)  # a frame's job: controlled by its sequence
    c.call("POST", f"/v1/jobs/{sq}.f1/pause", expect=409)
    c.call("POST", f"/v1/jobs/{b}/retry", {"frames": [1]}, expect=400)  # not a sequence
    _, page = c.call("GET", f"/v1/jobs/{sq}/frames?limit=1", expect=200)
    if [f["frame"] for f in page["frames"]] != [1] or page["next"] != 1:
        failures.append(f"GET /v1/jobs/{{id}}/frames?limit=1: {page}")
    _, page = c.call("GET", f"/v1/jobs/{sq}/frames?after=1", expect=200)
    if [f["frame"] for f in page["frames"]] != [3] or page["next"] is not None:
        failures.append(f"GET /v1/jobs/{{id}}/frames?after=1: {page}")
    c.call("GET", f"/v1/jobs/{sq}/frames?limit=0", expect=400)
    c.call("GET", f"/v1/jobs/{b}/frames", expect=409)  # not a sequence
    c.call("GET", "/v1/jobs/j-none/frames", expect=404)
    status, exr = c.call("GET", f"/v1/jobs/{sq}/frames/3/result.exr", expect=200)
    if status == 200 and exr[:4] != b"\x76\x2f\x31\x01":
        failures.append("a frame's result.exr is not an OpenEXR file")
    c.call("GET", f"/v1/jobs/{sq}/frames/2/result.exr", expect=404)
    c.call("GET", f"/v1/jobs/{sq}/result.exr", expect=409)  # each frame has its own
    c.call("POST", f"/v1/jobs/{sq}/retry", {"frames": [1]}, expect=409)  # done: nothing to retry
    c.call("POST", f"/v1/jobs/{sq}/retry", {"frames": [2]}, expect=404)
    c.call("POST", f"/v1/jobs/{sq}/retry", {"frames": "1-2"}, expect=400)
    c.call("POST", f"/v1/jobs/{sq}.f1/retry", expect=409)  # a frame's job is controlled through its sequence
    c.call("GET", f"/v1/jobs/{sq}/spec", expect=409)  # each frame has its own
    c.call("GET", f"/v1/jobs/{sq}.f1/spec", expect=200)
    c.call("DELETE", f"/v1/jobs/{sq}.f1?purge=true", expect=409)
    c.call("DELETE", f"/v1/jobs/{sq}?purge=true", expect=200)  # with its frames
    c.call("GET", f"/v1/jobs/{sq}.f1", expect=404)

    # One request per tile: an upload that asks (X-Tessera-Next-Lease, a lease request) carries the worker's next
    # lease under "next", as the lease route answers it; without the header the answer is the status alone.
    _, n = c.call("POST", "/v1/jobs", job, expect=201)
    upload = f"/v1/leases/{lb['lease']}/result"
    ask = {"X-Tessera-Next-Lease": json.dumps({"known_jobs": []})}
    c.call("PUT", upload, b"x", "image/x-exr", expect=400, headers={"X-Tessera-Next-Lease": '{"wait_ms": 100}'})
    _, settled = c.call("PUT", upload, b"x", "image/x-exr", expect=200, headers=ask)
    nxt = settled.get("next", {}) if isinstance(settled, dict) else {}
    if settled.get("status") != "duplicate" or nxt.get("job") != n.get("id") or "spec" not in nxt:
        failures.append(f"an upload asking for its next lease: {settled}")
    _, plain = c.call("PUT", upload, b"x", "image/x-exr", expect=200)
    if plain != {"status": "duplicate"}:
        failures.append(f"an upload not asking for its next lease: {plain}")
    if "lease" in nxt:
        c.call("POST", f"/v1/leases/{nxt['lease']}/heartbeat", expect=200)  # w2's, like a lease from the route
    c.call("DELETE", f"/v1/jobs/{n['id']}", expect=200)
    c.call("DELETE", f"/v1/jobs/{n['id']}?purge=true", expect=200)

    # The stream saw all of it, in order, ending with job b done and then the sequence's two frames done (each
    # frame_done after the job event of its frame's job done).
    seen, ids, b_done, frames_done, frame_jobs_done = [], [], False, set(), set()
    frames_wanted = {1, 3} if sequence_done else set()
    while True:
        e = events.next()
        if e is None:
            failures.append(f"GET /v1/events ended before job {b} and the frames of {sq} were done; saw {seen}")
            break
        seen.append(e[0])
        ids.append(int(e[1].rsplit("-", 1)[1]))
        if e[0] == "job" and e[2]["id"] == b and e[2]["state"] == "done":
            b_done = True
        if e[0] == "job" and e[2].get("sequence") == sq and e[2]["state"] == "done":
            frame_jobs_done.add(e[2]["id"])
        if e[0] == "frame_done" and e[2]["job"] == sq:
            frames_done.add(e[2]["frame"])
            if e[2]["frame_job"] != f"{sq}.f{e[2]['frame']}" or e[2]["frame_job"] not in frame_jobs_done:
                failures.append(f"frame_done {e[2]}: not frame {e[2]['frame']}'s job, or before its job event done")
        if b_done and frames_done >= frames_wanted:
            break
    events.close()
    expected = ["job", "tile_leased", "tile_done", "tile_failed", "worker_seen"] + (["frame_done"] if frames_wanted else [])
    for name in expected:
        if name not in seen:
            failures.append(f"GET /v1/events: no {name} event in {seen}")
    if ids != list(range(1, len(ids) + 1)):
        failures.append(f"GET /v1/events: ids are not 1, 2, 3, ...: {ids}")

    # Raised to 2 spp: running again, each tile's lease names its stored state, which the worker can fetch.
    c.call("PATCH", f"/v1/jobs/{b}", {"spp": 1}, expect=409)  # not higher
    _, raised = c.call("PATCH", f"/v1/jobs/{b}", {"spp": 2}, expect=200)
    if raised["state"] != "running" or raised["spp"] != 2 or raised["tiles"]["done"] != 0:
        failures.append(f"raise: the job is {raised['state']} at {raised['spp']} spp, {raised['tiles']['done']} tiles done")
    _, w3 = c.call("POST", "/v1/workers", None, expect=201)
    _, l4 = c.call("POST", f"/v1/workers/{w3['id']}/lease", expect=200)
    if not l4.get("resumable") or l4.get("state_spp") != 1 or l4["spp"] != 2:
        failures.append(f"lease of a raised job: {l4}")
    status, state = c.call("GET", f"/v1/leases/{l4['lease']}/state", expect=200)
    if status == 200 and state[:4] != b"\x76\x2f\x31\x01":
        failures.append("a lease's state is not an OpenEXR file")
    c.call("GET", "/v1/leases/l-none/state", expect=404)
    c.call("POST", "/v1/workers", None, expect=503)  # --max-workers 4: w1, w2, the real worker and w3
    c.call("DELETE", f"/v1/jobs/{b}", expect=200)  # cancels the raised job
    # Listings filtered and paged, and purges: a + b are the jobs so far (both cancelled).
    _, page = c.call("GET", "/v1/jobs?state=done,cancelled&limit=1", expect=200)
    if [j["id"] for j in page["jobs"]] != [b] or not page["next"]:
        failures.append(f"GET /v1/jobs?state=done,cancelled&limit=1: {page}")
    else:
        _, rest = c.call("GET", f"/v1/jobs?state=done,cancelled&limit=1&after={page['next']}", expect=200)
        if [j["id"] for j in rest["jobs"]] != [a] or rest["next"] is not None:
            failures.append(f"the second page is not job {a} alone: {rest}")
    c.call("GET", "/v1/jobs?state=finished", expect=400)
    c.call("GET", "/v1/jobs?limit=0", expect=400)
    c.call("GET", "/v1/jobs?after=j-none", expect=400)
    c.call("DELETE", f"/v1/jobs/{b}?purge=maybe", expect=400)
    c.call("DELETE", "/v1/jobs/j-none?purge=true", expect=404)
    _, purged = c.call("DELETE", f"/v1/jobs/{b}?purge=true", expect=200)
    if purged != {"id": b, "purged": True, "was": "cancelled"}:
        failures.append(f"purge answer: {purged}")
    c.call("GET", f"/v1/jobs/{b}", expect=404)
    c.call("DELETE", f"/v1/jobs/{b}?purge=true", expect=404)

    # 429: the coordinator runs with --max-queued-jobs 1 and no worker is left.
    _, q = c.call("POST", "/v1/jobs", job, expect=201)
    c.call("POST", "/v1/jobs", job, expect=429)
    c.call("DELETE", f"/v1/jobs/{q['id']}?purge=true", expect=409)  # queued: not ended


def main():
    self_test()
    route_table_agrees()
    workdir = tempfile.mkdtemp(prefix="tessera-openapi-")
    ready = os.path.join(workdir, "ready")
    serve = subprocess.Popen([TESSERA, "serve", "--listen", "127.0.0.1:0", "--data", os.path.join(workdir, "data"),
                              "--ready-file", ready, "--max-queued-jobs", "1", "--max-workers", "4"],
                             stdout=subprocess.DEVNULL, stderr=open(os.path.join(workdir, "serve.log"), "w"))
    try:
        deadline = time.time() + 30
        while not (os.path.exists(ready) and open(ready).read().strip()):
            if serve.poll() is not None or time.time() > deadline:
                sys.exit("the coordinator did not start:\n" + open(os.path.join(workdir, "serve.log")).read())
            time.sleep(0.05)
        address = open(ready).read().strip()
        exercise(Coordinator(address), TESSERA, workdir, address)
    finally:
        serve.send_signal(signal.SIGTERM)
        serve.wait(timeout=30)
    documented = {(p, m) for p, ops in DOC["paths"].items() for m in ops
                  if m in ("get", "put", "post", "delete", "head", "patch")}
    for p, m in sorted(documented - covered):
        failures.append(f"{m.upper()} {p} was not exercised")
    if failures:
        print("\n".join(failures))
        print(f"logs kept in {workdir}")
        sys.exit(1)
    shutil.rmtree(workdir)
    print(f"{len(covered)} operations answered as docs/openapi.yaml says")


main()
