"""``vpforms.native.available() -> (bool, reason)``: can generated C kernels run here?"""

from .backends.native.build import available

__all__ = ["available"]
