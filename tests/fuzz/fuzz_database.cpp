// libFuzzer harness: the session database (an SQLite file). The store opens
// and validates (or migrates) it, then `avsi export` reads every table.
#include <system_error>

#include "avsi/experiment/store.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    return avsi::fuzz::run(data, size, [](std::string_view bytes) {
        // No journal of the previous input may be applied to this one.
        const auto dir = avsi::fuzz::input_file("probe", "").parent_path();
        std::error_code ec;
        for (const char* f : {"db.sqlite-wal", "db.sqlite-shm", "db.sqlite-journal"}) std::filesystem::remove(dir / f, ec);
        std::filesystem::remove_all(dir / "export", ec);
        const auto path = avsi::fuzz::input_file("db.sqlite", bytes);
        const avsi::experiment::Store store(path);
        (void)store.schema_version();
        (void)avsi::experiment::export_store(store, dir / "export");
    });
}
