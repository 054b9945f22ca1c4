"""DuckDB over a campaign's Parquet tables (tests/campaign.rs): how many files it reads (all
tables at once, their columns united by name), the mean OCR^K per model over every scan of every
drive, the runs that passed their check, the cells of the validations, and the mean OCR^K per
model in 5 m bins of distance. Prints one JSON object.

usage: campaign_duckdb.py OUT
"""
import json
import sys

import duckdb

out = sys.argv[1]
con = duckdb.connect()
files = con.execute(
    f"select count(distinct filename) from read_parquet('{out}/tables/*/*.parquet', "
    f"union_by_name = true, filename = true)"
).fetchone()[0]
ocr = con.execute(
    f"select model, avg(ocr), count(ocr), count(distinct drive) "
    f"from read_parquet('{out}/tables/compare_scans/*.parquet') group by model order by model"
).fetchall()
runs = con.execute(
    f"select count(*), count(distinct drive) "
    f"from read_parquet('{out}/tables/check_runs/*.parquet') where verdict = 'pass'"
).fetchone()
cells = con.execute(
    f"select count(*) from read_parquet('{out}/tables/validate_cells/*.parquet')"
).fetchone()[0]
# OCR^K over distance in 5 m bins per model, over every scan of every drive: the report's
# pooled figure, computed here from the tables alone.
fleet = con.execute(
    f"select model, cast(floor(mean_distance_m / 5) as integer) as bin, count(*), "
    f"count(distinct drive), avg(ocr), stddev_samp(ocr) "
    f"from read_parquet('{out}/tables/compare_scans/*.parquet') "
    f"where ocr is not null and mean_distance_m is not null "
    f"group by model, bin order by model, bin"
).fetchall()
print(json.dumps({"files": files, "ocr": ocr, "runs": runs, "cells": cells, "fleet": fleet}))
