import json

import pytest
import torch

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_lab.cnn.models import build_model, load_weights, read_checkpoint


def test_inception_v3_keys_and_shapes_match_torchvision(keys_fixture):
    fx = json.loads(keys_fixture.read_text())
    expected = [(k, tuple(s)) for k, s in fx["keys"]]
    model, _ = build_model("inception_v3", 1000, aux_logits=True)
    got = [(k, tuple(v.shape)) for k, v in model.state_dict().items()]
    assert got == expected  # same names, shapes and order: a torchvision file loads directly


def test_small_inception_is_stem_plus_head_of_the_full_network(keys_fixture):
    fx = dict((k, tuple(s)) for k, s in json.loads(keys_fixture.read_text())["keys"])
    small, _ = build_model("small_inception", 4)
    sd = small.state_dict()
    assert {k.split(".")[0] for k in sd} == {
        "Conv2d_1a_3x3", "Conv2d_2a_3x3", "Conv2d_2b_3x3", "Conv2d_3b_1x1", "Conv2d_4a_3x3", "fc"}
    for k, v in sd.items():
        if not k.startswith("fc."):
            assert fx[k] == tuple(v.shape)
    assert tuple(sd["fc.weight"].shape) == (4, 192)
    out = small(torch.randn(3, 3, 299, 299))
    assert out.shape == (3, 4)


def _torchvision_like_checkpoint(tmp_path, keys_fixture):
    """A file with exactly torchvision's keys/shapes (random values), as torch.save writes it."""
    fx = json.loads(keys_fixture.read_text())["keys"]
    g = torch.Generator().manual_seed(0)
    state = {k: (torch.randn(s, generator=g) if s else torch.tensor(7)) for k, s in fx}
    path = tmp_path / "inception_v3_imagenet.pth"
    torch.save(state, path)
    return path, state


def test_checkpoint_loads_tensor_by_tensor_and_head_is_replaced(tmp_path, keys_fixture):
    path, state = _torchvision_like_checkpoint(tmp_path, keys_fixture)
    model, report = build_model("inception_v3", 4, aux_logits=True, weights=path)
    assert report.ok and len(report.loaded) == len(state) - 4
    assert sorted(report.reset) == sorted(["fc.weight", "fc.bias", "AuxLogits.fc.weight",
                                           "AuxLogits.fc.bias"])
    sd = model.state_dict()
    assert torch.equal(sd["Mixed_7c.branch_pool.conv.weight"],
                       state["Mixed_7c.branch_pool.conv.weight"])
    assert sd["fc.weight"].shape == (4, 2048)
    small, rep2 = build_model("small_inception", 4, weights=path)
    assert rep2.ok and torch.equal(small.state_dict()["Conv2d_4a_3x3.conv.weight"],
                                   state["Conv2d_4a_3x3.conv.weight"])


def test_bad_checkpoint_is_reported_tensor_by_tensor(tmp_path, keys_fixture, capsys):
    path, state = _torchvision_like_checkpoint(tmp_path, keys_fixture)
    state["Mixed_6b.branch1x1.conv.weight"] = torch.zeros(3, 3)
    del state["Conv2d_1a_3x3.bn.running_var"]
    bad = tmp_path / "bad.pth"
    torch.save(state, bad)
    rep = load_weights(build_model("inception_v3", 4)[0], read_checkpoint(bad))
    assert rep.missing == ["Conv2d_1a_3x3.bn.running_var"]
    assert [m[0] for m in rep.mismatched] == ["Mixed_6b.branch1x1.conv.weight"]
    with pytest.raises(InputError, match="Mixed_6b.branch1x1.conv.weight"):
        build_model("inception_v3", 4, weights=bad)
    assert main(["weights", "inspect", str(bad)]) == 1
    assert main(["weights", "inspect", str(path)]) == 0
    garbage = tmp_path / "garbage.pth"
    garbage.write_bytes(b"not a checkpoint")
    assert main(["weights", "inspect", str(garbage)]) == 2
    assert main(["weights", "inspect", str(tmp_path / "absent.pth")]) == 2


def test_unknown_model_name_is_named():
    with pytest.raises(InputError, match="resnet"):
        build_model("resnet", 4)


def test_block_dropout_adds_no_state_keys():
    a, _ = build_model("inception_v3", 4)
    b, _ = build_model("inception_v3", 4, block_dropout=0.2)
    assert list(a.state_dict()) == list(b.state_dict())
