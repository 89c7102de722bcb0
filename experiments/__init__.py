"""Entry points: Hydra wiring (config schemas, the run job), the Rerun recording, reproduction and benchmarks.

Rerun's own log lines are off unless ``RUST_LOG`` says otherwise (set before Rerun is imported): a failure of the
recording (a full disk) is reported once, by the run, with the path (``RUST_LOG=warn`` shows Rerun's too).
"""

import os

os.environ.setdefault("RUST_LOG", "off")
