"""Shared env machinery: the env contract, variants, input checking."""

from lfd_envs.core.base_env import OBS_MODES, LfdEnv
from lfd_envs.core.errors import (as_real_array, check_array, check_bool, check_choice, check_float, check_image_size,
                                  check_init_kwargs, check_int_range, check_str,
                                  strict_kwargs, StrictInitKwargs)
from lfd_envs.core.variants import SPLITS, VariantSplit

__all__ = [
    "LfdEnv", "OBS_MODES", "VariantSplit", "SPLITS",
    "as_real_array", "check_array", "check_bool", "check_choice", "check_float", "check_image_size",
    "check_init_kwargs", "check_int_range", "check_str", "strict_kwargs", "StrictInitKwargs",
]
