"""The evaluation dashboard: a local web server that shows runs live and after the fact, from the results
directory alone (paper, appendix "Evaluation Execution Layer Details")."""
