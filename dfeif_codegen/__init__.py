"""dfeif-codegen: symbolic flat robot models to verified embedded C for distributed
derivative-free Kalman filtering under packet drops and variable delays."""

__version__ = "0.1.0"
