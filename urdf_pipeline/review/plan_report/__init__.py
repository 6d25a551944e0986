"""`plan`: the plan's report, one typed model rendered as text, markdown, json and html. Named `plan_report`, not
`plan`, so it is not taken for the Plan dataclasses (`urdf_pipeline/plan/`)."""
