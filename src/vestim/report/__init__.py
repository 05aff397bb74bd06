"""Figures and reports for users: PNG figures (``figures``, ``plots``), the self-contained
HTML report (``html``), and the conventions they share (``style``, ``data``)."""
