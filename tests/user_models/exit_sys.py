"""A model file that ends the process while it is imported (tests/hostile/model_sys_exit_at_import.toml):
loading a model is an input step, so this is exit 2 naming this line, not exit 0 with nothing done."""
import sys

sys.exit(0)
