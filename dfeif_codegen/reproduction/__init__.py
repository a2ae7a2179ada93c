"""`codegen reproduce` (`dc.reproduce`): every table and figure of docs/experiment.md from one
command. `tasks.py` the simulate calls and their storage, `document.py` the numbers and the
rendering, `run.py` the command; `chapter_tables.toml` the chapter's own tables as printed."""
