"""launch_testing's pytest plugin (launch_testing.pytest.hooks) implements
``pytest_pycollect_makemodule(path, parent)``; pytest 9 removed the ``path`` argument, so the
plugin aborts every pytest run where launch_testing is importable (a sourced ROS 2 environment).
``make test`` therefore runs with ``-p no:launch_testing`` (pyproject.toml) and the launch tests
here are run by launch_testing itself: ``launch_test test/launch/test_explore_launch.py`` (or
``colcon test``, CMakeLists.txt ``add_launch_test``). Without the plugin, pytest must not collect
them as plain modules: where launch_testing is importable they are ignored (and the header of
the run says so); where it is not, the test module skips itself with the reason.
"""

from __future__ import annotations

import importlib.util


def _plugin_active(config) -> bool:
    return config.pluginmanager.hasplugin("launch_testing")


def _importable() -> bool:
    return importlib.util.find_spec("launch_testing") is not None


def pytest_ignore_collect(collection_path, config):
    if (collection_path.suffix == ".py" and collection_path.name.startswith("test_")
            and _importable() and not _plugin_active(config)):
        return True
    return None


def pytest_report_header(config):
    if _importable() and not _plugin_active(config):
        return ("test/launch: not collected by pytest (launch_testing plugin off); run "
                "`launch_test test/launch/test_explore_launch.py` on a ROS 2 system")
    return None
