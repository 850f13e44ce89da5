#!/usr/bin/env python3
"""docs/openapi.yaml against the protocol's types: for every wire type, the JSON that protocol_schema_dump prints of a
value with every optional field set ("full") and of a default value ("minimal") is compared with the type's schema.

- Every key the code writes is a property of the schema, and every property is a key the code writes (full);
- every required property is written even by a default value (minimal);
- nested objects are compared the same way where the schema describes them (properties, $ref, array items).
A schema with additionalProperties as a map (no properties of its own) accepts any keys.

usage: check_types.py SCHEMA_DUMP_BINARY SOURCE_DIR
"""
import json
import os
import subprocess
import sys

import yaml

dump_bin, source = sys.argv[1], sys.argv[2]
doc = yaml.safe_load(open(os.path.join(source, "docs", "openapi.yaml")))
schemas = doc["components"]["schemas"]
dump = json.loads(subprocess.run([dump_bin], check=True, capture_output=True, text=True).stdout)
problems = []


def resolve(schema):
    while isinstance(schema, dict) and "$ref" in schema:
        schema = schemas[schema["$ref"].rsplit("/", 1)[1]]
    return schema


def properties(schema):
    """The properties and required names of an object schema, allOf parts merged."""
    schema = resolve(schema)
    props, required = dict(schema.get("properties", {})), set(schema.get("required", []))
    for part in schema.get("allOf", []):
        p, r = properties(part)
        props.update(p)
        required |= r
    return props, required


def compare(where, schema, full, minimal):
    schema = resolve(schema)
    if isinstance(full, list):
        items = schema.get("items")
        if items is not None and full:
            compare(where + "[]", items, full[0], (minimal or [None])[0] if isinstance(minimal, list) else None)
        return
    if not isinstance(full, dict):
        return
    props, required = properties(schema)
    if not props:
        return  # a map (additionalProperties) or a free object: any keys
    for key in sorted(set(full) - set(props)):
        problems.append(f"{where}: the code writes '{key}', which the document does not list")
    for key in sorted(set(props) - set(full)):
        problems.append(f"{where}: the document lists '{key}', which the code never writes")
    for key in sorted(required - set(props)):
        problems.append(f"{where}: '{key}' is required but not a property")
    if isinstance(minimal, dict):
        for key in sorted(required - set(minimal)):
            problems.append(f"{where}: '{key}' is required, but a default value does not write it")
    for key, sub in props.items():
        if key in full:
            compare(f"{where}.{key}", sub, full[key], minimal.get(key) if isinstance(minimal, dict) else None)


for name, values in sorted(dump.items()):
    if name not in schemas:
        problems.append(f"{name}: no schema of that name in docs/openapi.yaml")
        continue
    compare(name, schemas[name], values["full"], values["minimal"])

for p in problems:
    print(p)
print(f"openapi types: {len(dump)} types compared, {len(problems)} problem(s)")
sys.exit(1 if problems else 0)
