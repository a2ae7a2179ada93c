"""The numpy reference: node filters, late measurements, fusion, control, closed loop."""
