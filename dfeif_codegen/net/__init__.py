"""The estimator on a real network: the wire format (Python twin of the generated C), the UDP
programs, the seeded relay that emulates the scenario's network, and `codegen network`."""
