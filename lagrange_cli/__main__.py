from lagrange_cli.cli import main

main()
