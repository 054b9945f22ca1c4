"""SALib's eFAST analyzer on the outputs in a file (one per line, header skipped), for the
parameter names given and M: prints a JSON list of {name, S1, ST, S1_conf, ST_conf}, the
confidence half-widths from the bootstrap windows given as the fourth argument (default 10)."""
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
    resamples = int(sys.argv[4]) if len(sys.argv) > 4 else 10
    si = fast.analyze(problem, y, M=int(sys.argv[3]), num_resamples=resamples, seed=1)
print(json.dumps([{"name": n, "S1": float(a), "ST": float(b), "S1_conf": float(c),
                   "ST_conf": float(d)}
                  for n, a, b, c, d in zip(names, si["S1"], si["ST"], si["S1_conf"],
                                           si["ST_conf"])]))
