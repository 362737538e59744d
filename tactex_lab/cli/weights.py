"""``tactex weights inspect``: what a checkpoint loads into a thesis model."""

from __future__ import annotations

import argparse

from tactex_lab.cli.bench import device_text
from tactex_ros.cli.options import builds, write_json


def cmd_weights_inspect(args: argparse.Namespace) -> int:
    from tactex_lab.cnn.device import resolve_device
    from tactex_lab.cnn.models import build_model, load_weights, read_checkpoint
    device = resolve_device(args.device, "--device")
    state = read_checkpoint(args.path)                # on the CPU, whatever it was saved on
    model, _ = build_model(args.model, args.classes)
    model.to(device)
    report = load_weights(model, state)               # copied into the model on ``device``
    print(report.summary())
    write_json(args.json, report.to_dict())
    return 0 if report.ok else 1


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    w = sub.add_parser("weights", help="checkpoint tools")
    if not builds(command, "weights"):
        return
    wsub = w.add_subparsers(dest="wcmd", required=True)
    wi = wsub.add_parser("inspect", help="what a checkpoint loads into a model")
    wi.add_argument("path")
    wi.add_argument("--model", default="inception_v3")
    wi.add_argument("--classes", type=int, default=4, help="platforms (classifier size)")
    wi.add_argument("--device", type=device_text, default="cpu",
                    help="load into a model on this torch device: cpu, cuda, cuda:N or auto")
    wi.add_argument("--json")
    wi.set_defaults(func=cmd_weights_inspect)
