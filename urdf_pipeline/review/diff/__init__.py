"""`diff`: the semantic difference of two compiled plans (`diff_plans.py`, robots in `diff_robots.py`), its report
(`diff_base.py`), renderings (`diff_render.py`) and inputs, files or a git revision (`diff_inputs.py`). Its names reach
other packages through `review/__init__.py`."""
