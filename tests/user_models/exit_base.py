"""A model file that raises a BaseException of its own (not an Exception) while it is imported
(tests/hostile/model_base_exception_at_import.toml)."""


class Stop(BaseException):
    pass


raise Stop("no model today")
