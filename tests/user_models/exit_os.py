"""A model file that calls os._exit while it is imported (tests/model/test_model_exits.py, in a process
of its own: os._exit cannot be caught, mechsweep replaces it while a model loads)."""
import os

os._exit(0)
