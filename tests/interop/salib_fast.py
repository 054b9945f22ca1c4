"""SALib's eFAST analyzer on the outputs in a file (one per line, header skipped), for the
parameter names given: prints a JSON list of {name, S1, ST}."""
import json
import sys
import warnings

import numpy as np
from SALib.analyze import fast

names = sys.argv[2].split(",")
y = np.loadtxt(sys.argv[1], skiprows=1)
problem = {"num_vars": len(names), "names": names, "bounds": [[-np.pi, np.pi]] * len(names)}
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    si = fast.analyze(problem, y, M=int(sys.argv[3]), num_resamples=10, seed=1)
print(json.dumps([{"name": n, "S1": float(a), "ST": float(b)}
                  for n, a, b in zip(names, si["S1"], si["ST"])]))
