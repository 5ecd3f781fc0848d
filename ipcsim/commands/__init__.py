"""One module per subcommand; each has ``main(args) -> int``."""
