"""`python harness/compare.py OLD NEW`: compare two result sets (`collide-bench compare`)."""

import runpy
from pathlib import Path

if __name__ == "__main__":
    runpy.run_path(str(Path(__file__).with_name("launch.py")),
                   {"COMMAND": "compare", "SCRIPT": __file__}, "__main__")
