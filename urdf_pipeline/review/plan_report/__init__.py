"""`plan`: the plan's report, one typed model (`report_model.py`) built by `report.py` and rendered by `report_text.py`,
`report_markdown.py` and `report_json.py`. Named `plan_report`, not `plan`, so it is not taken for the Plan dataclasses
(`urdf_pipeline/plan.py`). Its names reach other packages through `review/__init__.py`."""
