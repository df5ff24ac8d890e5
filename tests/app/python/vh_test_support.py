"""What the Python module's tests share: the command line under test and the source tree."""
import os
import pathlib
import subprocess

#: The volume-haptics program under test (ctest sets VH_CLI to the built one).
CLI = os.environ.get("VH_CLI", "volume-haptics")
#: The source tree (ctest sets VH_SOURCE_DIR).
SOURCE = pathlib.Path(os.environ.get("VH_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[3]))


def cli(*args, check=True):
    """Runs `volume-haptics ARGS...` without a display; with check, a non-zero exit fails the
    test with the program's standard error."""
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True,
                       env=dict(os.environ, QT_QPA_PLATFORM="offscreen"))
    if check and p.returncode != 0:
        raise AssertionError("volume-haptics %s failed (%d): %s" % (" ".join(map(str, args)), p.returncode, p.stderr))
    return p
