"""Command-line subcommands of foldbot: one module per command (add_arguments + run)."""
