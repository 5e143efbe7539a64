COMMANDS = {"demo": ("tools.demo.main", "run the whole pipeline on a simulated apartment, live, then score it")}
