"""dfeif-codegen: symbolic flat robot models to verified embedded C for distributed
derivative-free Kalman filtering under packet drops and variable delays.

The public API, in the order data flows:

    model = load_model("dc_motor_link")   # symbolic model (a built-in name, a .toml path)
    flat = derive(model)                  # flatness transform, canonical form, discretization
    module = build(model, "out")          # CasADi kernels + templates -> out/<model>/
    lib = load(module)                    # compiled with the host compiler, loaded with ctypes
    node = lib.Node(x0, P0, R, q)         # the generated C as Python objects (see README)

Names are imported on first use, so `codegen --version` does not load sympy and CasADi.
"""

__version__ = "0.1.0"

_API = {
    "load_model": ("dfeif_codegen.symbolic.model", "load"),
    "from_sympy": ("dfeif_codegen.symbolic.model", "from_sympy"),
    "derive": ("dfeif_codegen.symbolic.flatness", "derive"),
    "build": ("dfeif_codegen.codegen.build", "build"),
    "check_build": ("dfeif_codegen.codegen.build", "check"),
    "load": ("dfeif_codegen.check.loader", "load"),
    "inspect": ("dfeif_codegen.symbolic.inspect_model", "inspect"),
    "verify": ("dfeif_codegen.check.verify", "verify"),
    "bench": ("dfeif_codegen.check.bench", "bench"),
    "simulate": ("dfeif_codegen.api", "simulate"),
    "scenario": ("dfeif_codegen.experiment.starter", "scenario"),
    "network": ("dfeif_codegen.net.run", "network"),
    "CError": ("dfeif_codegen.check.loader", "CError"),
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        import importlib

        module, attr = _API[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dfeif_codegen' has no attribute {name!r}")
