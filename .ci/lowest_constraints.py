"""Print a pip constraints file that pins every declared dependency to the lowest version its range allows.

Reads pyproject.toml: the core dependencies, the extras named on the command line (default: test) and the
build dependency group. A requirement `name>=X` (or `name~=X`, `name==X`) becomes `name==X`; one without a
lower bound is left to the resolver. Used by .ci/run's lowest-versions job.
"""

import re
import sys
import tomllib
from pathlib import Path

project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
extras = sys.argv[1:] or ["test"]
requirements = list(project["project"]["dependencies"]) + project["dependency-groups"]["build"]
optional = project["project"]["optional-dependencies"]
pending = list(extras)
while pending:
    for requirement in optional[pending.pop()]:
        nested = re.fullmatch(r"pinstab\[([\w,-]+)\]", requirement.replace(" ", ""))
        if nested:
            pending.extend(nested.group(1).split(","))
        else:
            requirements.append(requirement)
lowest = {}
for requirement in requirements:
    match = re.match(r"\s*([A-Za-z0-9_.-]+)(\[[^\]]*\])?\s*[^;]*?(?:>=|~=|==)\s*([0-9][^,;\s]*)", requirement)
    if match:
        lowest[match.group(1).lower()] = match.group(3)
print("\n".join(f"{name}=={version}" for name, version in sorted(lowest.items())))
