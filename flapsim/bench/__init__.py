"""Speed benchmarks, one module per system; each reports ratios measured in one run
(``flapsim bench TARGET``)."""
