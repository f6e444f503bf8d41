"""What users run: the CLI, comparisons, convergence studies, reports."""
