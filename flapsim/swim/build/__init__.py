"""The generator of the bundled swimmer (``swimmer_mjcf/swimmer.xml``):
``python -m flapsim.swim.build.swimmer``. The bundled file is its output, byte for byte."""
