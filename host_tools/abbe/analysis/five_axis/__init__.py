"""Five-axis identification: sphere fits, the parameter problem, observability, the fit
and its report (docs/concepts.md, "Five-axis machines")."""
