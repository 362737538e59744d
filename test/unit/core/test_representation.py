"""Prepared representation: fit on a library, file round trip, refusal of bad files, and the
`tactex prepare` -> `tactex trial --representation` path on real presses built at test time."""

import json

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core import representation as rp
from tactex_ros.core.errors import InputError
from tactex_ros.core.texture import DIM


def _library(rng, noisy_dims=(0, 1)):
    """Classes differ in every dimension by ~1; dims ``noisy_dims`` vary 10x more within a
    class than the others."""
    out = {}
    for c in range(6):
        centre = rng.normal(0, 1.0, DIM)
        x = centre + rng.normal(0, 0.1, (5, DIM))
        x[:, list(noisy_dims)] += rng.normal(0, 1.0, (5, len(noisy_dims)))
        out[f"k{c}"] = x
    return out


def test_fit_downweights_dimensions_that_vary_within_a_class(tmp_path):
    rep = rp.fit(_library(np.random.default_rng(0)), shrink=0.01)
    w = np.abs(np.diag(rep.whiten))
    assert w[:2].max() < 0.5 * np.median(w[2:])
    path = rp.save(rep, tmp_path / "r.npz")
    back = rp.load(path)
    np.testing.assert_allclose(back.whiten, rep.whiten)
    x = np.random.default_rng(1).normal(size=(3, DIM))
    np.testing.assert_allclose(back.apply(x), ((x - rep.mean) / rep.std) @ rep.whiten.T)
    assert (back.classes, back.presses) == (6, 30)


def test_bad_representation_files_are_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="not found"):
        rp.load(tmp_path / "missing.pt")
    (tmp_path / "junk.pt").write_bytes(b"not an archive")
    with pytest.raises(InputError, match="not loadable"):
        rp.load(tmp_path / "junk.pt")
    with (tmp_path / "other.npz").open("wb") as f:
        np.savez(f, format=np.array("other"))
    with pytest.raises(InputError, match="not a tactex-representation"):
        rp.load(tmp_path / "other.npz")
    with (tmp_path / "small.npz").open("wb") as f:
        np.savez(f, format=np.array(rp.FORMAT), mean=np.zeros(3), std=np.ones(3),
                 whiten=np.eye(3))
    with pytest.raises(InputError, match="do not fit"):
        rp.load(tmp_path / "small.npz")
    with pytest.raises(InputError, match="at least 2"):
        rp.fit({"a": np.zeros((3, DIM)), "b": np.zeros((1, DIM))})


@pytest.mark.slow
def test_prepare_then_trial_with_the_file(octopi_dir, tmp_path):
    lib = tmp_path / "lib"
    for cls in ("rice", "millet", "sponge"):
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    out = tmp_path / "rep.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(out)]) == 0
    assert rp.load(out).presses == 6
    js = tmp_path / "t.json"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--classes",
                 "basket,tissue,wires", "--reference", "tissue", "--seed", "1",
                 "--representation", str(out), "--json", str(js), "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert d["model"] == "descriptor" and d["truth"] == "c2"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--representation",
                 str(tmp_path / "nope.pt")]) == 2
