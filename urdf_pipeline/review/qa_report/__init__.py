"""`qa`: the dataset QA report rendered from its record form, and the --fail-on gate (the data pass is execute/qa_pass.py)."""
