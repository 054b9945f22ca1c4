"""scipy's first Wasserstein distance of the sample pairs in a JSON file (a list of [a, b]):
prints one number per pair, full precision."""
import json
import sys

from scipy.stats import wasserstein_distance

for a, b in json.load(open(sys.argv[1])):
    print(repr(float(wasserstein_distance(a, b))))
