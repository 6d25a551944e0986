"""`diff`: the semantic difference of two compiled plans, from two files or a git revision."""
