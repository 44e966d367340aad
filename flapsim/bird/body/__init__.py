"""The dove's body: parameters, MJCF, feather geometry, feather bending modes and their
dynamics."""
