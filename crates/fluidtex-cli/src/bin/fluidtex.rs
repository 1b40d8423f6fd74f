fn main() {
    fluidtex_cli::run()
}
