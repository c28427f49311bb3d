from symid.cli.entry import command

command()
