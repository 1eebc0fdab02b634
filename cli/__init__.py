"""vfit's command line (installed as the ``vfit_cli`` package, command ``vfit``)."""
