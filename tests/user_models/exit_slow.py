"""A model file whose import takes long (tests/model/test_model_exits.py): it writes the file named by
MECHSWEEP_TEST_STARTED, then sleeps, so that a real Ctrl-C or SIGTERM arrives during the import."""
import os
import pathlib
import time

pathlib.Path(os.environ["MECHSWEEP_TEST_STARTED"]).write_text("importing")
time.sleep(120)
