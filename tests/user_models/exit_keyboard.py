"""A model file that raises KeyboardInterrupt itself while it is imported (tests/model/test_model_exits.py):
no Ctrl-C was pressed, so this is a bad model (exit 2), not an interruption (exit 130)."""
raise KeyboardInterrupt
