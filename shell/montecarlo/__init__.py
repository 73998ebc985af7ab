"""Monte Carlo campaigns over scenarios (TM-2020-5008164 App. D: Dshell's large-scale Monte Carlo).

campaign.py  the campaign YAML schema and one run (draws -> --set overrides -> build -> run -> metrics)
draws.py     distributions, per-(master seed, run, dispersion) random streams, correlated draws
metrics.py   final values, extrema, RMS, settling time of logged signals
executors.py serial, local process pool, Dask distributed; run_campaign drives one of them
results.py   the results HDF5 (table of draws + metrics, kept signals, metadata), journal, resume
report.py    percentile tables and PNG charts
"""
