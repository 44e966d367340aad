"""Forces from air and water, shared by the bird and the swimmer.

``surfaces``: oriented polygons on bodies -> drag, lift, friction -> body wrenches;
``coefficients``: CL/CD tables with their sources; ``flow``: wind and current fields;
``buoyancy``: partial submersion of ellipsoids.
"""
