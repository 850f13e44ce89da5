#!/usr/bin/env python3
"""A webhook receiver for the farm tests: listens on 127.0.0.1 (port written to PORT_FILE), checks each delivery's
signature (HMAC-SHA256 keyed by the secret over "timestamp.body"), answers 500 to the first FAIL_FIRST requests and
200 to the others, and appends one JSON line per request to LOG: id, event, job, path, signature_ok, answered.

usage: webhook_receiver.py PORT_FILE LOG SECRET FAIL_FIRST"""
import hashlib
import hmac
import http.server
import json
import sys
import threading

port_file, log_file, secret, fail_first = sys.argv[1], sys.argv[2], sys.argv[3].encode(), int(sys.argv[4])
lock = threading.Lock()
seen = 0


class Handler(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        global seen
        body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
        stamp = self.headers.get("X-Tessera-Timestamp", "")
        want = "sha256=" + hmac.new(secret, stamp.encode() + b"." + body, hashlib.sha256).hexdigest()
        ok = hmac.compare_digest(want, self.headers.get("X-Tessera-Signature", ""))
        event = json.loads(body)
        with lock:
            seen += 1
            status = 500 if seen <= fail_first else 200
            with open(log_file, "a") as f:
                f.write(json.dumps({"id": event["id"], "header_id": self.headers.get("X-Tessera-Event-Id"),
                                    "event": event["event"], "job": event["job"]["id"], "path": self.path,
                                    "signature_ok": ok, "answered": status, "links": event["links"]}) + "\n")
        self.send_response(status)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def log_message(self, *args):
        pass


server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
with open(port_file + ".tmp", "w") as f:
    f.write(str(server.server_address[1]))
import os
os.rename(port_file + ".tmp", port_file)
server.serve_forever()
