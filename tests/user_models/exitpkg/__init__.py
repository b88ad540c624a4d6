"""A package whose module ends the process at import (tests/model/test_model_exits.py: "exitpkg.models:M")."""
