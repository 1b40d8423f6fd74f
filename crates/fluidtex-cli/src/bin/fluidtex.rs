fn main() {
    std::process::exit(fluidtex_cli::main_entry());
}
