#!/usr/bin/env python3
"""The parameter declarations of CRISP's CartesianController, as names, types, defaults and lines.

    scripts/crisp_params.py extract CHECKOUT --rev REV --release REL [--out FILE]

CHECKOUT is a copy of crisp_controllers (``git clone https://github.com/learnsyslab/crisp_controllers
&& git -C crisp_controllers checkout vX.Y.Z``; the repository was utiasDSL/crisp_controllers).
Its ``src/cartesian_controller.yaml`` is the generate_parameter_library declaration the
controller's ``ParamListener`` is generated from; every leaf (a mapping with a ``type``) becomes
one entry ``{name, type, default, line}``: the dotted parameter name as ``ros2 param`` shows it
(``__map_joints`` kept as written: one such parameter per joint), the declared
``default_value`` (absent: the parameter is required), its bounds when declared, and the
1-based line of its key in that file. The list (config/upstream/crisp_cartesian_controller.yaml)
is what the profiles' and bring-ups' citations and test/unit/robot/test_bringup.py read: the
parameters whose default is the -1 sentinel ("if negative, computed as 2 sqrt(stiffness)") are
taken from it, not typed by hand.

Exit status 0; 2 when the checkout has no such file or it is not a parameter declaration.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

DECLARATION = Path("src/cartesian_controller.yaml")
ROOT = "cartesian_controller"


def _leaves(node: yaml.MappingNode, prefix: str) -> list[dict]:
    """Every declared parameter under ``node``: [{name, type, default?, bounds?, line}]."""
    out: list[dict] = []
    for key, value in node.value:
        name = f"{prefix}.{key.value}" if prefix else key.value
        if not isinstance(value, yaml.MappingNode):
            continue
        fields = {k.value: v for k, v in value.value}
        if "type" in fields:
            entry: dict = {"name": name, "type": fields["type"].value,
                           "line": key.start_mark.line + 1}
            if "default_value" in fields:
                entry["default"] = yaml.safe_load(yaml.serialize(fields["default_value"]))
            validation = fields.get("validation")
            if isinstance(validation, yaml.MappingNode):
                for vk, vv in validation.value:
                    if vk.value == "bounds<>":
                        entry["bounds"] = yaml.safe_load(yaml.serialize(vv))
            out.append(entry)
        else:
            out.extend(_leaves(value, name))
    return out


def extract(checkout: Path) -> list[dict]:
    """The declarations of ``checkout/src/cartesian_controller.yaml``, in file order.

    Raises ValueError when the file is not a generate_parameter_library declaration of
    ``cartesian_controller``; OSError when it cannot be read."""
    text = (checkout / DECLARATION).read_text()
    root = yaml.compose(text)
    if not isinstance(root, yaml.MappingNode):
        raise ValueError(f"{checkout / DECLARATION}: not a mapping")
    top = {k.value: v for k, v in root.value}
    if ROOT not in top or not isinstance(top[ROOT], yaml.MappingNode):
        raise ValueError(f"{checkout / DECLARATION}: no top-level '{ROOT}' mapping")
    params = _leaves(top[ROOT], "")
    if not params:
        raise ValueError(f"{checkout / DECLARATION}: no parameter declarations")
    return params


def main(argv: list[str] | None = None) -> int:
    """Command line: write the list (see the module docstring); returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    ex = sub.add_parser("extract", help="write the declarations of a checkout")
    ex.add_argument("checkout", type=Path)
    ex.add_argument("--rev", required=True, help="commit of the checkout (40 or short hex)")
    ex.add_argument("--release", required=True, help="release the commit belongs to, e.g. 2.3.1")
    ex.add_argument("--repo", default="utiasDSL/crisp_controllers")
    ex.add_argument("--note", default="", help="how the commit was tied to the release")
    ex.add_argument("--out", type=Path, default=Path("config/upstream/crisp_cartesian_controller.yaml"))
    args = ap.parse_args(argv)
    try:
        params = extract(args.checkout)
    except (OSError, ValueError, yaml.YAMLError) as e:
        print(f"crisp_params: {e}", file=sys.stderr)
        return 2
    doc = {"repo": args.repo, "release": args.release, "rev": args.rev,
           "file": str(DECLARATION)}
    if args.note:
        doc["note"] = args.note
    doc["parameters"] = params
    header = ("# CRISP CartesianController parameter declarations (facts: names, types, defaults,\n"
              f"# bounds, line of each key in {args.repo}@{args.rev}:{DECLARATION}).\n"
              "# Regenerate: scripts/crisp_params.py extract CHECKOUT --rev REV --release REL\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(header + yaml.safe_dump(doc, sort_keys=False, width=100))
    sentinels = [p["name"] for p in params if p.get("default") == -1.0]
    print(f"{len(params)} parameters, -1 sentinels: {', '.join(sentinels)} -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
