"""Where the CNN learners run: ``learner.device`` resolved against what torch reports.

The product validates the setting's form only (``core/config.py``, ``DEVICE_PATTERN``: ``cpu``,
``cuda``, ``cuda:N``, ``auto``); whether the device exists is checked here, where torch is
imported, when a learner is built (before the trial's first touch):

- ``cpu``: today's path, nothing global is changed;
- ``cuda`` / ``cuda:N``: refused (InputError, exit 2) when torch sees no CUDA or fewer than N+1
  devices, naming the device and what torch reports;
- ``auto``: the first CUDA device when torch sees one, else the CPU (a console line says which).

On a CUDA device with ``learner.deterministic`` (the default) the learner asks torch for
deterministic kernels (``torch.use_deterministic_algorithms(True, warn_only=True)``, cuDNN
deterministic without benchmarking, ``CUBLAS_WORKSPACE_CONFIG=:4096:8``): a seeded trial then
repeats on the same GPU and software, except for the few CUDA kernels torch has no
deterministic version of (it warns about those, e.g. the backward of adaptive average pooling).
These are process-wide torch settings; they are never touched on the CPU path.
"""

from __future__ import annotations

import os
import sys

import torch

from tactex_ros.core.errors import InputError

_SAID: set[str] = set()


def cuda_report() -> str:
    """What torch reports about CUDA, for messages: availability, device count, build."""
    avail = torch.cuda.is_available()
    count = torch.cuda.device_count() if avail else 0
    return (f"torch {torch.__version__} reports torch.cuda.is_available() = {avail}, "
            f"{count} CUDA device(s), built for CUDA {torch.version.cuda or 'none (CPU wheel)'}")


def resolve_device(text: str, origin: str = "learner.device") -> torch.device:
    """``'cpu' | 'cuda' | 'cuda:N' | 'auto'`` -> the torch device the learner uses.

    InputError (exit 2) names the device and what torch reports when a CUDA device is asked
    for and absent; ``auto`` without CUDA says on the console (stderr, once per process) that
    it runs on the CPU."""
    text = text.strip()
    if text == "cpu":
        return torch.device("cpu")
    if text == "auto":
        if torch.cuda.is_available() and torch.cuda.device_count() > 0:
            dev = torch.device("cuda:0")
            _say(f"{origin} 'auto': running on {dev} ({torch.cuda.get_device_name(0)})")
            return dev
        _say(f"{origin} 'auto': no CUDA device, running on the CPU ({cuda_report()})")
        return torch.device("cpu")
    if text != "cuda" and not text.startswith("cuda:"):
        raise InputError(f"{origin} {text!r}: choose 'cpu', 'cuda', 'cuda:N' or 'auto'")
    index = 0 if text == "cuda" else int(text.split(":", 1)[1])
    if not torch.cuda.is_available() or index >= torch.cuda.device_count():
        raise InputError(f"{origin} {text!r}: no such CUDA device ({cuda_report()}); use "
                         "'cpu', or 'auto' to fall back to the CPU")
    return torch.device("cuda", index)


def _say(line: str) -> None:
    if line not in _SAID:
        _SAID.add(line)
        print(line, file=sys.stderr, flush=True)


def configure(device: torch.device, deterministic: bool) -> None:
    """Process-wide torch settings for a learner on ``device``: on CUDA with ``deterministic``
    the deterministic kernels (see the module docstring); on CUDA without it cuDNN may pick the
    fastest (non-deterministic) algorithms. Nothing on the CPU."""
    if device.type != "cuda":
        return
    if deterministic:
        # must be set before cuBLAS creates its handle (the first matrix product on the GPU)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        torch.backends.cudnn.benchmark = False
        torch.backends.cudnn.deterministic = True
        torch.use_deterministic_algorithms(True, warn_only=True)
    else:
        torch.backends.cudnn.deterministic = False
        torch.backends.cudnn.benchmark = True
        torch.use_deterministic_algorithms(False)


def rng_devices(device: torch.device) -> list:
    """The devices whose random state ``torch.random.fork_rng`` must save and restore around a
    seeded block on ``device`` (dropout masks drawn there): none on the CPU."""
    return [device] if device.type == "cuda" else []


def to_cpu(obj):
    """``obj`` (tensors in dicts / lists / tuples) with every tensor on the CPU, so a saved
    state loads on any machine; CPU tensors are returned as they are."""
    if isinstance(obj, torch.Tensor):
        return obj.cpu()
    if isinstance(obj, dict):
        return {k: to_cpu(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(to_cpu(v) for v in obj)
    return obj
