"""``python -m vestim``: the command line, as the ``vestim`` script."""

from vestim.cli import app

app(prog_name="vestim")
