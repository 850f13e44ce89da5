#!/usr/bin/env python3
"""Compares every protocol type's JSON form, as the code writes it (protocol/schema_dump.cpp), with its schema in
docs/openapi.yaml: the field names and the required fields. No coordinator is started.

protocol_schema_dump prints schema name -> C++ type -> {"answer", "full", "minimal"}: "full" is a value with every
optional field set and every list non-empty, "minimal" a default-constructed one. For each entry:

- the keys of "full" are exactly the schema's properties (a key the code writes that the document lacks fails, and so
  does a documented property the code never writes);
- the schema's required names are among its properties, and each appears in "minimal" (the code always writes it);
- for an answer (what the coordinator writes), every key of "minimal" is required: a key always written is documented
  as always there; a null in "minimal" is a property marked nullable;
- "full" holds no null and no empty list (the sample must set everything, or the comparison misses fields).

Nested values are compared the same way wherever the schema describes them: a property whose schema (after $ref) has
properties is compared with the nested object of "full" and "minimal", and an array's items with each item of "full".
allOf: the parts' properties and required names are merged into one object (JobSubmission and JobSpec are Sampling's
keys plus their own). oneOf: the value must have exactly the properties of one branch, which is then compared. A schema
that is a map (additionalProperties a schema, no properties, e.g. Assets) has no fixed keys: only its values are
walked. An object schema without properties (the scene) is free-form and not walked.

Every schema of components/schemas must be the schema of some dumped type, except maps (which name no fields).

usage: check_types.py PROTOCOL_SCHEMA_DUMP SOURCE_DIR
"""
import json
import os
import subprocess
import sys

import yaml


def load_document(source):
    with open(os.path.join(source, "docs", "openapi.yaml")) as f:
        return yaml.safe_load(f)


class Checker:
    def __init__(self, doc):
        self.doc = doc
        self.problems = []

    def resolve(self, schema):
        """The schema a $ref (or a chain of them) points at."""
        seen = 0
        while "$ref" in schema and seen < 20:
            node = self.doc
            for part in schema["$ref"].removeprefix("#/").split("/"):
                node = node[part]
            schema, seen = node, seen + 1
        return schema

    def merged(self, schema):
        """(properties, required) of an object schema with the parts of its allOf merged in."""
        schema = self.resolve(schema)
        props, required = dict(schema.get("properties", {})), list(schema.get("required", []))
        for part in schema.get("allOf", []):
            p, r = self.merged(part)
            props.update(p)
            required += [name for name in r if name not in required]
        return props, required

    def is_map(self, schema):
        schema = self.resolve(schema)
        return isinstance(schema.get("additionalProperties"), dict) and not self.has_fields(schema)

    def has_fields(self, schema):
        schema = self.resolve(schema)
        return any(k in schema for k in ("properties", "allOf", "oneOf"))

    def object(self, where, full, minimal, schema, answer):
        """Compares one object of the sample with an object schema, then walks its nested values."""
        schema = self.resolve(schema)
        if "oneOf" in schema:
            branches = [b for b in schema["oneOf"] if set(self.merged(b)[0]) == set(full)]
            if len(branches) != 1:
                self.problems.append(f"{where}: its keys {sorted(full)} are the properties of {len(branches)} of the "
                                     f"oneOf branches, not 1")
                return
            schema = self.resolve(branches[0])
        props, required = self.merged(schema)
        for key in sorted(set(full) - set(props)):
            self.problems.append(f"{where}: the code writes {key!r}, which docs/openapi.yaml does not document")
        for key in sorted(set(props) - set(full)):
            self.problems.append(f"{where}: docs/openapi.yaml documents {key!r}, which the code never writes")
        for key in required:
            if key not in props:
                self.problems.append(f"{where}: required {key!r} is not one of the schema's properties")
        if isinstance(minimal, dict):
            for key in required:
                if key not in minimal:
                    self.problems.append(f"{where}: {key!r} is required, but the code leaves it out of a minimal value")
            for key, value in minimal.items():
                if answer and key not in required:
                    self.problems.append(f"{where}: the code always writes {key!r}, which the schema does not require")
                if value is None and key in props and not self.resolve(props[key]).get("nullable"):
                    self.problems.append(f"{where}: the code writes {key!r} as null, which the schema does not allow "
                                         f"(nullable)")
        for key, value in full.items():
            if key in props:
                inner = minimal.get(key) if isinstance(minimal, dict) else None
                self.value(f"{where}.{key}", value, inner, props[key], answer)

    def value(self, where, full, minimal, schema, answer):
        """Walks one value of the sample wherever its schema names fields."""
        schema = self.resolve(schema)
        if full is None:
            self.problems.append(f"{where}: null in the full sample (set it, so its schema is compared)")
        elif isinstance(full, list):
            if not full:
                self.problems.append(f"{where}: empty in the full sample (fill it, so its items are compared)")
            items = schema.get("items", {})
            for i, item in enumerate(full):
                inner = minimal[i] if isinstance(minimal, list) and i < len(minimal) else None
                self.value(f"{where}[{i}]", item, inner, items, answer)
        elif isinstance(full, dict):
            if self.is_map(schema):
                for key, item in full.items():
                    self.value(f"{where}[{key!r}]", item, None, schema["additionalProperties"], answer)
            elif self.has_fields(schema):
                self.object(where, full, minimal, schema, answer)


def main():
    dump_binary, source = sys.argv[1], sys.argv[2]
    doc = load_document(source)
    schemas = doc["components"]["schemas"]
    dumped = json.loads(subprocess.run([dump_binary], check=True, capture_output=True, text=True).stdout)
    checker = Checker(doc)
    count = 0
    for name, types in sorted(dumped.items()):
        for type_name, entry in sorted(types.items()):
            if name not in schemas:
                checker.problems.append(f"{name} ({type_name}): no schema {name!r} in docs/openapi.yaml's "
                                        f"components/schemas")
                continue
            where = name if name == type_name else f"{name} ({type_name})"
            checker.value(where, entry["full"], entry["minimal"], schemas[name], entry["answer"])
            count += 1
    for name in sorted(set(schemas) - set(dumped)):
        if not checker.is_map(schemas[name]):
            checker.problems.append(f"{name}: a schema of docs/openapi.yaml that no protocol type is dumped as "
                                    f"(protocol/schema_dump.cpp)")
    if checker.problems:
        print("\n".join(checker.problems))
        sys.exit(1)
    print(f"{count} protocol types have the fields docs/openapi.yaml documents")


main()
