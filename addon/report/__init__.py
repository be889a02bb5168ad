"""The report: speed against error of every method over views, budgets and seeds."""
