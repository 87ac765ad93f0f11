"""Model updating: correlation, parameters, residuals, solver, diagnosis, reports, CLI."""
