"""The generators of the bundled creature models (``creatures/*.xml``).

``python -m flapsim.modal.build.creatures`` writes the loop and linear creatures,
``python -m flapsim.modal.build.dog_human`` the dog, the human and the human with the cart.
Each bundled file is its generator's output, byte for byte.
"""
