"""Test-run settings shared by every test module.

Property tests are derandomized: hypothesis draws the same examples on every run (seeded from
each test's name), so CI cannot fail by chance on an example no earlier run drew. A new
counter-example is found by running with ``HYPOTHESIS_PROFILE=explore`` (random draws, 10×
the examples), and then kept with ``@example``.
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False, max_examples=1000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
