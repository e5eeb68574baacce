"""The vehicle model fitted to logs (`rov-mav identify`): the regression, its solution, and the check before writing.

- dive_runs: a vehicle's own DataFlash log as identification data, a pilot's dive included
- estimation: small dense nonlinear estimation: bounded least squares, instrumental variables, collinearity
- force_balance: the force balance integrated over windows of a flown run: the regression
- identification: the fit: which parameters the data show, their values and intervals
- prediction_check: the fit's one-second-ahead prediction on held-back data beside the prior's
"""
