from fsi.cli import run_console

run_console()
