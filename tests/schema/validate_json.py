#!/usr/bin/python3
"""Validates a JSON file against a JSON Schema (draft 2020-12) with Debian's python3-jsonschema.

    validate_json.py SCHEMA.json INSTANCE.json

Prints every violation with its path in the instance; exit 0 when there is none, 1 otherwise,
2 when a file cannot be read. NaN and infinities are refused too: they are not JSON.
"""
import json
import sys

import jsonschema


def refuse_constant(name):
    raise ValueError(f"{name} is not JSON")


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        with open(sys.argv[1]) as f:
            schema = json.load(f)
        with open(sys.argv[2]) as f:
            instance = json.load(f, parse_constant=refuse_constant)
    except (OSError, ValueError) as e:
        print(f"validate_json: {e}", file=sys.stderr)
        return 2
    validator_class = jsonschema.validators.validator_for(schema)
    validator_class.check_schema(schema)
    errors = sorted(validator_class(schema).iter_errors(instance), key=lambda e: list(e.absolute_path))
    for e in errors:
        path = "/".join(str(p) for p in e.absolute_path) or "(root)"
        print(f"{sys.argv[2]}: {path}: {e.message}")
    if errors:
        print(f"{sys.argv[2]}: {len(errors)} violation(s) of {sys.argv[1]}")
        return 1
    print(f"{sys.argv[2]}: valid against {sys.argv[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
