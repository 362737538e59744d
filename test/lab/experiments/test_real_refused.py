"""`tactex experiment real` on a folder whose presses are all refused by the contact guard
(blank frames): exit 2 naming the folder, not an IndexError from an empty belief curve."""

import cv2
import numpy as np

from tactex_ros.cli.main import main


def test_all_presses_refused_exit_2_naming_the_folder(tmp_path, capsys):
    lib = tmp_path / "blank"
    for c in "abcdef":
        (lib / c).mkdir(parents=True)
        for i in range(3):
            cv2.imwrite(str(lib / c / f"{i}.png"), np.full((240, 320, 3), 90, np.uint8))
    assert main(["experiment", "real", "--source", f"replay:{lib}", "--scenes", "1",
                 "--budget", "2", "--folds", "2", "--comparisons", "2",
                 "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(lib) in err and "Traceback" not in err
