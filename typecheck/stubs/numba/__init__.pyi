# numba read as untyped by pyright (typecheck/README.md)
from typing import Any

def __getattr__(name: str) -> Any: ...
