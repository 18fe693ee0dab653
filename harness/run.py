"""`python harness/run.py CONFIG...`: measure experiments (`collide-bench run`)."""

import runpy
from pathlib import Path

if __name__ == "__main__":
    runpy.run_path(str(Path(__file__).with_name("launch.py")),
                   {"COMMAND": "run", "SCRIPT": __file__}, "__main__")
