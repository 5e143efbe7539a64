COMMANDS = {"demo": ("services.demo.main", "run the whole pipeline on a simulated apartment, live, then score it")}
