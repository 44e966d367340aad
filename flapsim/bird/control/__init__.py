"""The learned wingbeat controller: targets, regression, predictions of S0, the controller
and the database it reads."""
