"""`plan`: the plan's report, one typed model (`report_model.py`, its plain data `as_data` the json) built by `report.py`
and rendered by `report_text.py`, `report_markdown.py` and `report_html.py`. Named `plan_report`, not `plan`, so it is not
taken for the Plan dataclasses (`urdf_pipeline/plan/`). Its names reach other packages through `review/__init__.py`."""
