"""The partial-contact guard (``ContactGuard.inspect``) and the descriptor over a contact region:
exact values on constructed frames."""

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialConfig, TrialEngine
from tactex_ros.core.errors import InputError
from tactex_ros.core.guards import ContactGuard, contact_region, press_verdict
from tactex_ros.core.texture import (DIM, PARTS, contact_difference, describe_difference,
                                     height_map)
from tactex_ros.core.touch import Touch


def _half_touch(seed: int = 0) -> Touch:
    """Textured no-contact frame; the contact frame +2 grey levels in every channel, plus
    texture, on columns 0..159 only (the left half)."""
    rng = np.random.default_rng(seed)
    nc = np.clip(100 + rng.normal(0, 3, (240, 320, 3)), 0, 255).astype(np.uint8)
    f = nc.astype(np.float32)
    f[:, :160] += 2 + rng.normal(0, 6, (240, 160, 3))
    return Touch(frame=np.clip(np.rint(f), 0, 255).astype(np.uint8), no_contact=nc)


def test_contact_region_of_a_half_contact_is_half_the_frame():
    nc = np.full((240, 320, 3), 100, np.uint8)
    f = nc.copy()
    f[:, :160] += 2               # 6 grey levels summed over channels; 0 on the right half
    r = contact_region(f, nc)
    # inside the 16 px border: 288 columns, the step at column 160 - 16 = 144 crosses the
    # 3 grey level threshold half-way, so exactly the first 144 columns are in contact
    assert r.shape == (208, 288) and r.mean() == 0.5
    assert r[:, :144].all() and not r[:, 144:].any()
    assert contact_region(nc + 2, nc).all() and not contact_region(nc, nc).any()


def test_inspect_describes_a_partial_touch_over_its_region():
    t = _half_touch()
    ok, reason, out = ContactGuard(region_min=0.6).inspect(t)
    assert ok and reason.startswith("partial contact")
    region = contact_region(t.frame, t.no_contact)
    assert 0.45 < region.mean() < 0.6
    want = describe_difference(contact_difference(t.frame, t.no_contact), region)
    assert np.array_equal(out.descriptor, want) and out.frame is t.frame
    # a full contact, the guard off, or no no-contact frame: the touch as it was
    full = Touch(frame=t.frame, no_contact=np.clip(t.frame.astype(int) - 4, 0, 255)
                 .astype(np.uint8))
    assert ContactGuard(region_min=0.6).inspect(full)[2] is full
    assert ContactGuard(region_min=0.0).inspect(t)[2] is t
    bare = Touch(frame=t.frame)
    assert ContactGuard(region_min=0.6).inspect(bare) == (True, "", bare)


def test_region_descriptor_is_the_descriptor_of_the_region():
    rng = np.random.default_rng(1)
    d = rng.normal(0, 4, (208, 288, 3)).astype(np.float32)
    region = np.zeros((208, 288), bool)
    region[:, :144] = True
    cut = np.where(region[..., None], d, 0).astype(np.float32)
    whole, plain, guarded = (describe_difference(d), describe_difference(cut),
                             describe_difference(cut, region))
    inten, spec = slice(0, PARTS["intensity"]), slice(6, 6 + PARTS["spectrum"])
    # intensity over the region's pixels: exactly the left half's own
    assert np.array_equal(guarded[inten], describe_difference(d[:, :144].copy())[inten])
    # spectrum: the zeroed half costs the plain descriptor about log 2 per band; over the
    # region it is back within 0.15 of the uncut texture's
    assert np.abs(plain[spec] - whole[spec]).mean() > 0.5
    assert np.abs(guarded[spec] - whole[spec]).mean() < 0.15
    assert np.linalg.norm(guarded - whole) < 0.5 * np.linalg.norm(plain - whole)
    with pytest.raises(InputError, match="empty contact region"):
        describe_difference(d, np.zeros((208, 288), bool))
    with pytest.raises(InputError, match="region"):
        describe_difference(d, region[:10])


def test_engine_stores_the_partial_touch_described_over_its_region():
    t = _half_touch()
    stored: dict[str, list] = {"on": [], "off": []}
    engines = {"on": TrialEngine(2, preset("default", contact_region_min=0.6), TrialConfig()),
               "off": TrialEngine(2, preset("default"), TrialConfig())}
    for name, eng in engines.items():
        add = eng.learner.add_touch
        eng.learner.add_touch = lambda touch, label, _a=add, _n=name: (
            stored[_n].append(touch) or _a(touch, label))
        eng.add_touch(1, t)
    d, region = contact_difference(t.frame, t.no_contact), contact_region(t.frame, t.no_contact)
    want = describe_difference(d, region, with_height_map=True)   # the default descriptor's
    assert np.array_equal(stored["on"][0].descriptor, want)
    # the region's parts, then the height map of the whole difference
    assert np.array_equal(want[:DIM], describe_difference(d, region))
    assert np.array_equal(want[DIM:], height_map(d))
    assert stored["off"][0].descriptor is None                    # the guard's test is off
    assert engines["on"].touches.tolist() == [1, 0] and engines["on"].failed == []


def test_press_verdict_checks_a_press_against_its_own_no_contact_frame():
    """A recorded press is judged as a trial would judge it, with its own no-contact frame as
    the guard's reference: the no-contact frame itself has score 0 (rejected), a press 2 grey
    levels brighter with texture on the whole gel is accepted, a flat frame is blank."""
    t = _half_touch()
    nc = t.no_contact
    assert press_verdict(Touch(frame=nc, no_contact=nc))[0] is False
    whole = Touch(frame=_half_touch().frame[:, list(range(160)) * 2], no_contact=nc)
    assert press_verdict(whole) == (True, "")
    ramp = np.repeat(np.linspace(60, 160, 320)[None, :, None], 240, 0).repeat(3, 2)
    ok, reason = press_verdict(Touch(frame=ramp.astype(np.uint8), no_contact=nc))
    assert not ok and reason.startswith("blank frame")
    # not a sensor frame: refused with the validation's reason; an unusable no-contact frame
    # leaves the flatness check only
    assert press_verdict(Touch(frame=nc[:100], no_contact=nc))[0] is False
    assert press_verdict(Touch(frame=nc, no_contact=nc[:100])) == (True, "")
    # without a no-contact frame only the flatness check runs
    assert press_verdict(Touch(frame=nc)) == (True, "")
    # the thresholds are the caller's (the learner settings' contact_min)
    assert press_verdict(Touch(frame=nc, no_contact=nc), contact_min=0.0) == (True, "")
