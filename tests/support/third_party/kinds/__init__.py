"""Small plain-C FMUs of every FMI kind (1.0 CS, 2.0 ME/CS, 3.0 ME/CS): see build.py."""
from .build import (CO_SIMULATION, FMI_VERSIONS, MODEL_EXCHANGE, MODELS, TIME_VR,
                    TYPED_ARRAY_MODES, TYPED_ARRAY_VARIABLES, Model, Var, build_fmu,
                    build_memcheck, build_typed_array, model_description)

__all__ = ["CO_SIMULATION", "FMI_VERSIONS", "MODEL_EXCHANGE", "MODELS", "TIME_VR",
           "TYPED_ARRAY_MODES", "TYPED_ARRAY_VARIABLES", "Model", "Var", "build_fmu",
           "build_memcheck", "build_typed_array", "model_description"]
