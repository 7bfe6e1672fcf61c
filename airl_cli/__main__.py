from airl_cli.cli import main

main()
