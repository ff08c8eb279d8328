"""Settings shared by every test."""

from hypothesis import settings

# Property tests check what code does with any input, not how fast: hypothesis's default 200 ms deadline per
# example failed them on a loaded 2-core host (another suite beside them), with nothing wrong in the code.
settings.register_profile("rover", deadline=None)
settings.load_profile("rover")
