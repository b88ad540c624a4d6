"""A package whose module ends the process at import (tests/test_model_exits.py: "exitpkg.models:M")."""
