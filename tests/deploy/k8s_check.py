#!/usr/bin/python3
"""Offline checks of deploy/k8s (no cluster): every manifest against the Kubernetes API models of Debian's
python3-kubernetes (unknown keys, wrong types and missing required fields are errors), the references between
manifests (selectors, Service ports, probes, volumes, claims, the token Secret), the farm's rules (one coordinator
replica on a Recreate strategy, probes on /healthz, workers' grace period), every `tessera` flag the manifests use
against the built binary's --help, and finally the Indexed Job's own shell scripts, run here for every index with
the built binary, merged by the merge Job's script and compared bitwise with a single-process render.

Usage: k8s_check.py TESSERA EXR_COMPARE SOURCE_DIR
"""
import inspect
import os
import re
import shutil
import subprocess
import sys
import tempfile

try:
    import yaml
    import kubernetes.client as k8s
except ImportError as e:
    sys.exit(f"FAIL: {e}: install Debian's python3-yaml and python3-kubernetes (bash deploy/install-deps.sh)")

# The Secrets the operator creates (deploy/k8s/README.md): their names and keys.
SECRET_KEYS = {"tessera-tokens": {"client-token", "worker-token"}, "tessera-tls": {"tls.crt", "tls.key", "ca.crt"}}
# Flags naming a file that must come from a mounted volume.
FILE_FLAGS = ("--client-token-file", "--worker-token-file", "--token-file", "--tls-cert", "--tls-key", "--ca-file",
              "--tls-client-ca")
WORKER_MIN_GRACE_SECONDS = 120

errors = []


def error(where, message):
    errors.append(f"{where}: {message}")


# ---- schema: every key known, every value of the model's type, required fields present.

def model_class(api_version, kind):
    version = api_version.split("/")[-1]
    return getattr(k8s, version[0].upper() + version[1:] + kind, None)


def required_fields(cls):
    """Python attribute names whose setters refuse None (the generated models' required fields)."""
    required = set()
    for attr in cls.openapi_types:
        prop = getattr(cls, attr, None)
        if isinstance(prop, property) and prop.fset and "must not be `None`" in inspect.getsource(prop.fset):
            required.add(attr)
    return required


def check_value(value, type_name, where):
    if type_name == "object":
        return
    if type_name.startswith("list["):
        if not isinstance(value, list):
            return error(where, f"expected a list ({type_name}), got {type(value).__name__}")
        for i, item in enumerate(value):
            check_value(item, type_name[5:-1], f"{where}[{i}]")
        return
    if type_name.startswith("dict("):
        if not isinstance(value, dict):
            return error(where, f"expected a map ({type_name}), got {type(value).__name__}")
        inner = type_name[5:-1].split(", ", 1)[1]
        for k, v in value.items():
            check_value(v, inner, f"{where}.{k}")
        return
    simple = {"str": str, "int": int, "bool": bool, "float": (int, float), "datetime": str, "date": str}
    if type_name in simple:
        ok = isinstance(value, simple[type_name]) and not (type_name == "int" and isinstance(value, bool))
        if not ok:
            error(where, f"expected {type_name}, got {type(value).__name__} {value!r}")
        return
    cls = getattr(k8s, type_name, None)
    if cls is None:
        return error(where, f"unknown model type {type_name}")
    check_model(value, cls, where)


def check_model(value, cls, where):
    if not isinstance(value, dict):
        return error(where, f"expected an object ({cls.__name__}), got {type(value).__name__}")
    json_to_attr = {j: a for a, j in cls.attribute_map.items()}
    for key, item in value.items():
        attr = json_to_attr.get(key)
        if attr is None:
            error(f"{where}.{key}", f"unknown field for {cls.__name__} (known: {', '.join(sorted(json_to_attr))})")
        elif item is not None:
            check_value(item, cls.openapi_types[attr], f"{where}.{key}")
    for attr in required_fields(cls):
        if value.get(cls.attribute_map[attr]) is None:
            error(where, f"{cls.__name__} needs '{cls.attribute_map[attr]}'")


# ---- loading

def load_manifests(k8s_dir):
    docs = []
    for root, _, files in os.walk(k8s_dir):
        for name in sorted(files):
            if not name.endswith(".yaml"):
                continue
            path = os.path.join(root, name)
            rel = os.path.relpath(path, k8s_dir)
            with open(path) as f:
                try:
                    loaded = [d for d in yaml.safe_load_all(f) if d is not None]
                except yaml.YAMLError as e:
                    error(rel, f"not valid YAML: {e}")
                    continue
            if name == "kustomization.yaml":
                for d in loaded:
                    for res in d.get("resources", []):
                        if not os.path.isfile(os.path.join(root, res)):
                            error(rel, f"resource {res} does not exist")
                continue
            for i, d in enumerate(loaded):
                docs.append((f"{rel}#{i}", os.path.relpath(root, k8s_dir), d))
    return docs


def pod_spec(doc):
    kind = doc["kind"]
    if kind == "Pod":
        return doc["spec"]
    if kind in ("Deployment", "Job", "StatefulSet", "DaemonSet"):
        return doc["spec"]["template"]["spec"]
    return None


# ---- tessera command lines

def help_flags(tessera, sub):
    out = subprocess.run([tessera, sub, "--help"], capture_output=True, text=True, check=False).stdout
    return set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", out))


def command_lines(container):
    """(subcommand, flags) for every tessera invocation in the container's command/args."""
    words = list(container.get("command") or []) + list(container.get("args") or [])
    if container.get("command") and os.path.basename(container["command"][0]) in ("sh", "bash"):
        script = " ".join(words[2:])
        return [(m.group(1), re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", m.group(2)))
                for m in re.finditer(r"\btessera (\w+)((?:[^\n]|\\\n)*)", script)]
    if container.get("command"):
        return []
    # The image's entry point is tessera itself: args are its command line.
    return [(words[0], [w for w in words[1:] if w.startswith("--")])] if words else []


def flag_value(container, flag):
    args = container.get("args") or []
    return args[args.index(flag) + 1] if flag in args and args.index(flag) + 1 < len(args) else None


# ---- the checks

def check_all(tessera, k8s_dir):
    docs = load_manifests(k8s_dir)
    if not docs:
        error(k8s_dir, "no manifests found")
        return []
    kinds = {}
    for where, _, d in docs:
        if not isinstance(d, dict) or "apiVersion" not in d or "kind" not in d:
            error(where, "not a Kubernetes object (apiVersion and kind needed)")
            continue
        cls = model_class(d["apiVersion"], d["kind"])
        if cls is None:
            error(where, f"unknown apiVersion/kind {d['apiVersion']} {d['kind']}")
            continue
        check_model(d, cls, f"{where} {d['kind']}")
        kinds.setdefault(d["kind"], []).append((where, d))
    if errors:
        return docs  # the reference checks below assume well-formed objects

    claims = {d["metadata"]["name"] for _, d in kinds.get("PersistentVolumeClaim", [])}
    helps = {}
    for where, folder, d in docs:
        spec = pod_spec(d)
        if spec is None:
            continue
        name = f"{where} {d['kind']}/{d['metadata']['name']}"
        template_labels = (d["spec"]["template"]["metadata"].get("labels", {}) if d["kind"] != "Pod"
                           else d["metadata"].get("labels", {}))
        selector = (d["spec"].get("selector") or {}).get("matchLabels", {}) if d["kind"] != "Pod" else {}
        for k, v in selector.items():
            if template_labels.get(k) != v:
                error(name, f"selector {k}={v} does not match the pod template's labels")
        volumes = {v["name"]: v for v in spec.get("volumes", [])}
        for v in volumes.values():
            if "persistentVolumeClaim" in v and v["persistentVolumeClaim"]["claimName"] not in claims:
                error(name, f"volume {v['name']} claims {v['persistentVolumeClaim']['claimName']}, "
                      "which no manifest defines")
            if "secret" in v:
                keys = SECRET_KEYS.get(v["secret"]["secretName"])
                if keys is None:
                    error(name, f"secret {v['secret']['secretName']} is not one of the documented {sorted(SECRET_KEYS)}")
                for item in v["secret"].get("items", []) if keys else []:
                    if item["key"] not in keys:
                        error(name, f"secret key {item['key']} is not one of {sorted(keys)}")
        for c in spec["containers"]:
            cname = f"{name} container {c['name']}"
            ports = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}
            mounts = {m["mountPath"]: m["name"] for m in c.get("volumeMounts", [])}
            for m in c.get("volumeMounts", []):
                if m["name"] not in volumes:
                    error(cname, f"mounts volume {m['name']}, which the pod does not define")
            for probe_name in ("startupProbe", "livenessProbe", "readinessProbe"):
                probe = c.get(probe_name)
                if probe and "httpGet" in probe:
                    port = probe["httpGet"]["port"]
                    if port not in ports and port not in ports.values():
                        error(cname, f"{probe_name} port {port} is not a container port")
                    if probe["httpGet"].get("path") != "/healthz":
                        error(cname, f"{probe_name} does not ask /healthz")
            env = {e["name"] for e in c.get("env", [])}
            for ref in re.findall(r"\$\((\w+)\)", " ".join(c.get("args", []))):
                if ref not in env:
                    error(cname, f"args use $({ref}), which the container's env does not define")
            for sub, flags in command_lines(c):
                if sub not in helps:
                    helps[sub] = help_flags(tessera, sub)
                    if not helps[sub]:
                        error(cname, f"`tessera {sub} --help` lists no flags: not a tessera subcommand?")
                for flag in flags:
                    if flag not in helps[sub]:
                        error(cname, f"`tessera {sub}` has no flag {flag}")
            for path in (flag_value(c, "--data"), flag_value(c, "--cache")):
                if path and not any(path == p or path.startswith(p.rstrip("/") + "/") for p in mounts):
                    error(cname, f"{path} is not on a mounted volume")
            for flag in FILE_FLAGS:
                path = flag_value(c, flag)
                if path and os.path.dirname(path) not in mounts:
                    error(cname, f"{flag} {path} is not in a mounted folder")
                elif path:
                    volume = volumes[mounts[os.path.dirname(path)]]
                    items = {i["path"]: i["key"] for i in (volume.get("secret") or {}).get("items", [])}
                    if items and os.path.basename(path) not in items:
                        error(cname, f"{flag} {path}: the mounted secret has no item {os.path.basename(path)}")

    # The farm: one coordinator, reachable through its Service, probed; workers point at that Service.
    deployments = {d["metadata"]["name"]: (w, d) for w, d in kinds.get("Deployment", [])}
    services = {d["metadata"]["name"]: (w, d) for w, d in kinds.get("Service", [])}
    coord = deployments.get("tessera-coordinator")
    workers = deployments.get("tessera-workers")
    svc = services.get("tessera-coordinator")
    if not coord or not workers or not svc:
        error("farm", "needs Deployments tessera-coordinator and tessera-workers and Service tessera-coordinator")
        return docs
    cw, cd = coord
    if cd["spec"].get("replicas") != 1:
        error(cw, "the coordinator must have exactly 1 replica (it owns its data folder)")
    if cd["spec"].get("strategy", {}).get("type") != "Recreate":
        error(cw, "the coordinator needs strategy Recreate (two pods must never share the data folder)")
    cc = cd["spec"]["template"]["spec"]["containers"][0]
    for probe in ("livenessProbe", "readinessProbe"):
        if probe not in cc:
            error(cw, f"the coordinator has no {probe}")
    # TLS: the coordinator serves HTTPS (so its probes must use it) and the workers verify it against the CA.
    if not flag_value(cc, "--tls-cert") or not flag_value(cc, "--tls-key"):
        error(cw, "the coordinator does not serve HTTPS (--tls-cert and --tls-key)")
    for probe in ("startupProbe", "livenessProbe", "readinessProbe"):
        get = (cc.get(probe) or {}).get("httpGet")
        if get and flag_value(cc, "--tls-cert") and get.get("scheme") != "HTTPS":
            error(cw, f"{probe} must use scheme HTTPS against a TLS coordinator")
    data = flag_value(cc, "--data")
    vols = {v["name"]: v for v in cd["spec"]["template"]["spec"].get("volumes", [])}
    data_mount = next((m for m in cc.get("volumeMounts", []) if data and data.startswith(m["mountPath"])), None)
    if not data_mount or "persistentVolumeClaim" not in vols.get(data_mount["name"], {}):
        error(cw, f"--data {data} is not on a persistent volume claim")
    listen = flag_value(cc, "--listen") or ""
    listen_port = int(listen.rsplit(":", 1)[1]) if ":" in listen else None
    if listen_port not in {p["containerPort"] for p in cc.get("ports", [])}:
        error(cw, f"--listen {listen} is not on a declared container port")
    sw, sd = svc
    for k, v in sd["spec"]["selector"].items():
        if cd["spec"]["template"]["metadata"]["labels"].get(k) != v:
            error(sw, f"selector {k}={v} does not select the coordinator's pods")
    named = {p.get("name"): p["containerPort"] for p in cc.get("ports", [])}
    for p in sd["spec"]["ports"]:
        target = p.get("targetPort", p["port"])
        if named.get(target, target) != listen_port:
            error(sw, f"port {p['port']} targets {target}, not the coordinator's port {listen_port}")
    ww, wd = workers
    wspec = wd["spec"]["template"]["spec"]
    if wspec.get("terminationGracePeriodSeconds", 30) < WORKER_MIN_GRACE_SECONDS:
        error(ww, f"terminationGracePeriodSeconds below {WORKER_MIN_GRACE_SECONDS}: a SIGTERMed worker finishes "
              "its tile first")
    url = flag_value(wspec["containers"][0], "--coordinator") or ""
    want = f"https://{sd['metadata']['name']}:{sd['spec']['ports'][0]['port']}"
    if not flag_value(wspec["containers"][0], "--ca-file"):
        error(ww, "workers do not say which CA to trust (--ca-file)")
    if url != want:
        error(ww, f"--coordinator {url} is not the Service's {want}")

    # The Indexed Job and its merge Job.
    jobs = {d["metadata"]["name"]: (w, d) for w, d in kinds.get("Job", [])}
    render, merge = jobs.get("tessera-render-strips"), jobs.get("tessera-merge-strips")
    if not render or not merge:
        error("indexed-job", "needs Jobs tessera-render-strips and tessera-merge-strips")
        return docs
    rw, rd = render
    if rd["spec"].get("completionMode") != "Indexed":
        error(rw, "completionMode must be Indexed")
    renv = env_values(rd)
    if str(rd["spec"].get("completions")) != renv.get("STRIPS"):
        error(rw, f"STRIPS={renv.get('STRIPS')} but completions={rd['spec'].get('completions')}")
    if rd["spec"].get("parallelism", 1) > rd["spec"].get("completions", 1):
        error(rw, "parallelism above completions")
    if env_values(merge[1]).get("STRIPS") != renv.get("STRIPS") or env_values(merge[1]).get("OUT") != renv.get("OUT"):
        error(merge[0], "STRIPS and OUT must be the render Job's")
    claim = lambda d: {v["persistentVolumeClaim"]["claimName"] for v in pod_spec(d).get("volumes", [])
                       if "persistentVolumeClaim" in v}
    if claim(rd) != claim(merge[1]):
        error(merge[0], "the merge Job must mount the render Job's volume")
    return docs


def env_values(job):
    return {e["name"]: e.get("value") for e in pod_spec(job)["containers"][0].get("env", []) if "value" in e}


def run_indexed_job(tessera, exr_compare, src, docs):
    """Runs the render Job's script for every index and the merge Job's script, here, with the built binary."""
    jobs = {d["metadata"]["name"]: d for _, _, d in docs if d.get("kind") == "Job"}
    render, merge = jobs["tessera-render-strips"], jobs["tessera-merge-strips"]
    renv = env_values(render)
    scene_name = os.path.basename(renv["SCENE"])
    scene = os.path.join(src, "scenes", scene_name)
    if not os.path.isfile(scene):
        return error("indexed-job", f"SCENE {renv['SCENE']} is not one of the project's scenes/ (checked here)")
    with open(scene) as f:
        width, height = yaml.safe_load(f)["film"]["resolution"]
    if (str(width), str(height)) != (renv["WIDTH"], renv["HEIGHT"]):
        return error("indexed-job", f"WIDTH x HEIGHT {renv['WIDTH']}x{renv['HEIGHT']} is not {scene_name}'s "
                     f"{width}x{height}")
    work = tempfile.mkdtemp(prefix="tessera-k8s-check.")
    try:
        bindir = os.path.join(work, "bin")
        os.makedirs(bindir)
        os.symlink(os.path.abspath(tessera), os.path.join(bindir, "tessera"))
        out = os.path.join(work, "out")
        # The manifests' values, except paths (this machine's) and spp (kept small: the check is about the pipeline).
        base = dict(os.environ, PATH=bindir + os.pathsep + os.environ["PATH"], SCENE=scene, OUT=out, SPP="2",
                    THREADS="2")
        spp, seed = "2", renv["SEED"]

        def script(job):
            c = pod_spec(job)["containers"][0]
            return c["command"], {**{k: v for k, v in env_values(job).items()}, **{k: base[k] for k in base}}

        cmd, env = script(render)
        strips = int(renv["STRIPS"])
        for i in range(strips):
            r = subprocess.run(cmd, env=dict(env, JOB_COMPLETION_INDEX=str(i)), capture_output=True, text=True)
            if r.returncode != 0:
                return error("render-job.yaml", f"index {i} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
        cmd, env = script(merge)
        r = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if r.returncode != 0:
            return error("merge-job.yaml", f"merge failed ({r.returncode}): {r.stderr.strip()[-400:]}")
        ref = os.path.join(work, "ref.exr")
        subprocess.run([tessera, "render", scene, "-o", ref, "--spp", spp, "--seed", seed, "-q"], check=True,
                       capture_output=True)
        r = subprocess.run([exr_compare, ref, os.path.join(out, "image.exr")], capture_output=True, text=True)
        if r.returncode != 0:
            return error("indexed-job", f"merged strips differ from the single-process render: {r.stdout}{r.stderr}")
        # A missing strip must stop the merge Job's script before tessera runs.
        os.remove(os.path.join(out, "strips", f"strip-{strips - 1}.exr"))
        os.remove(os.path.join(out, "image.exr"))
        r = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if r.returncode == 0 or os.path.exists(os.path.join(out, "image.exr")):
            return error("merge-job.yaml", "a missing strip was not an error")
        print(f"indexed job: {strips} strips of {scene_name} ({width}x{height}) merged bitwise identical to a "
              "single-process render; a missing strip is refused")
    finally:
        shutil.rmtree(work, ignore_errors=True)


# Mistakes the checks must catch: (file, text, replacement, expected error fragment). Each is applied to a copy of
# deploy/k8s before the real run, so a check that cannot fail is noticed.
MUTATIONS = [
    ("farm/workers.yaml", "terminationGracePeriodSeconds: 600", "terminationGracePeriodSecond: 600", "unknown field"),
    ("farm/workers.yaml", "terminationGracePeriodSeconds: 600", "terminationGracePeriodSeconds: 30",
     "terminationGracePeriodSeconds below"),
    ("farm/workers.yaml", "- --cache", "- --cache-dir", "has no flag --cache-dir"),
    ("farm/workers.yaml", "- --token-file", "- --token-path", "has no flag --token-path"),
    ("farm/coordinator.yaml", "- --worker-token-file", "- --worker-token", "has no flag --worker-token"),
    ("farm/workers.yaml", "- $(POD_NAME)", "- $(POD)", "does not define"),
    ("farm/workers.yaml", "https://tessera-coordinator:8470", "http://tessera-coordinator:8470", "not the Service's"),
    ("farm/workers.yaml", "- --ca-file ", "- --no-ca-file ", "do not say which CA"),
    ("farm/workers.yaml", "path: ca.crt", "path: ca.pem", "has no item ca.crt"),
    ("farm/workers.yaml", "secretName: tessera-tls", "secretName: tessera-cert", "not one of the documented"),
    ("farm/coordinator.yaml", "- --tls-key\n", "- --tls-keys\n", "has no flag --tls-keys"),
    ("farm/coordinator.yaml", "port: http, scheme: HTTPS}\n            periodSeconds: 10",
     "port: http}\n            periodSeconds: 10", "must use scheme HTTPS"),
    ("farm/coordinator.yaml", "mountPath: /etc/tessera/tls\n", "mountPath: /etc/tessera/certs\n",
     "is not in a mounted folder"),
    ("farm/coordinator.yaml", "replicas: 1 ", "replicas: 2 ", "exactly 1 replica"),
    ("farm/coordinator.yaml", "type: Recreate", "type: RollingUpdate", "strategy Recreate"),
    ("farm/coordinator.yaml", "periodSeconds: 10", "periodSeconds: ten", "expected int"),
    ("farm/coordinator.yaml", "httpGet: {path: /healthz, port: http, scheme: HTTPS}\n            periodSeconds: 5",
     "httpGet: {path: /health, port: http, scheme: HTTPS}\n            periodSeconds: 5", "does not ask /healthz"),
    ("farm/coordinator.yaml", "targetPort: http", "targetPort: 8471", "not the coordinator's port"),
    ("farm/coordinator.yaml", "claimName: tessera-data", "claimName: tessera-dat", "which no manifest defines"),
    ("farm/coordinator.yaml", "        - name: coordinator\n          image: tessera:0.1.0",
     "        - image: tessera:0.1.0", "needs 'name'"),
    ("farm/kustomization.yaml", "- workers.yaml", "- worker.yaml", "does not exist"),
    ("indexed-job/render-job.yaml", 'value: "8"', 'value: "7"', "STRIPS=7 but completions=8"),
    ("indexed-job/render-job.yaml", "completionMode: Indexed", "completionMode: NonIndexed", "must be Indexed"),
    ("indexed-job/render-job.yaml", '{name: WIDTH, value: "256"}', '{name: WIDTH, value: "255"}',
     "is not cbox_area_light.json's"),
    ("indexed-job/render-job.yaml", 'i * HEIGHT / STRIPS', 'i * HEIGHT / STRIPS + 1', "merge failed"),
]


def self_test(tessera, exr_compare, src):
    missed = []
    for rel, old, new, expected in MUTATIONS:
        work = tempfile.mkdtemp(prefix="tessera-k8s-mutant.")
        try:
            shutil.copytree(os.path.join(src, "deploy"), os.path.join(work, "deploy"))
            shutil.copytree(os.path.join(src, "scenes"), os.path.join(work, "scenes"))
            path = os.path.join(work, "deploy", "k8s", rel)
            with open(path) as f:
                text = f.read()
            if old not in text:
                missed.append(f"{rel}: the text to mutate ({old!r}) is gone; update MUTATIONS")
                continue
            with open(path, "w") as f:
                f.write(text.replace(old, new, 1))
            errors.clear()
            docs = check_all(tessera, os.path.join(work, "deploy", "k8s"))
            if not errors:
                run_indexed_job(tessera, exr_compare, work, docs)
            if not any(expected in e for e in errors):
                missed.append(f"{rel}: {old!r} -> {new!r} gave {errors or 'no error'}, not '{expected}'")
        finally:
            shutil.rmtree(work, ignore_errors=True)
    errors.clear()
    return missed


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    tessera, exr_compare, src = sys.argv[1:]
    missed = self_test(tessera, exr_compare, src)
    if missed:
        for m in missed:
            print("FAIL: mutation not caught:", m, file=sys.stderr)
        sys.exit(1)
    print(f"self-test: all {len(MUTATIONS)} deliberate mistakes were caught")
    docs = check_all(tessera, os.path.join(src, "deploy", "k8s"))
    if not errors:
        run_indexed_job(tessera, exr_compare, src, docs)
    if errors:
        for e in errors:
            print("FAIL:", e, file=sys.stderr)
        sys.exit(1)
    print(f"PASS: {len(docs)} Kubernetes objects checked")


if __name__ == "__main__":
    main()
