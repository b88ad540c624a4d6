"""A model file whose helper module ends the process while it is imported
(tests/hostile/model_helper_exits_at_import.toml): the message names the helper's line and this
file's import of it."""
import exit_helper_module  # noqa: F401
