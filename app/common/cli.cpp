#include "cli.h"

#include <algorithm>

namespace fulgur::app {

ImageSize parse_size(const std::string& v, const char* tool, const char* what, int lo, int hi) {
    const std::size_t x = v.find('x');
    if (x == std::string::npos) throw core::Error(tool, std::string(what) + " must be WxH, got '" + v + "'");
    ImageSize s;
    s.width = parse_number<int>(v.substr(0, x), tool, (std::string(what) + " width").c_str());
    s.height = parse_number<int>(v.substr(x + 1), tool, (std::string(what) + " height").c_str());
    if (s.width < lo || s.height < lo || s.width > hi || s.height > hi)
        throw core::Error(tool, std::string(what) + ": each side must be in " + std::to_string(lo) + ".." +
                                    std::to_string(hi) + ", got '" + v + "'");
    return s;
}

CommandLine::CommandLine(const char* tool, const std::string& description) : tool_(tool), app_(description, tool) {
    app_.set_help_flag("-h,--help", "print this help and exit");
    app_.footer(
        "Exit status: 0 done, 1 failure (an input that cannot be read or used, I/O, GL), 2 invalid command line "
        "(with a one-line reason).");
    app_.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    app_.allow_extras();  // parse() reports unknown options in the tools' words
    app_.get_formatter()->column_width(32);
}

std::string CommandLine::label(const std::string& names) {
    std::string best;
    std::size_t start = 0;
    while (start <= names.size()) {
        const std::size_t comma = std::min(names.find(',', start), names.size());
        const std::string n = names.substr(start, comma - start);
        if (best.empty() || (n.rfind("--", 0) == 0 && best.rfind("--", 0) != 0)) best = n;
        start = comma + 1;
    }
    return best;
}

void CommandLine::reject_unknown_options() const {
    for (const std::string& s : app_.remaining())
        if (s.size() > 1 && s[0] == '-') throw core::Error(tool_, "unknown option '" + s + "' (see --help)");
}

CLI::Option* CommandLine::size(const std::string& names, int& width, int& height, const std::string& help, int lo,
                               int hi) {
    const std::string name = label(names);
    const char* tool = tool_;
    CLI::Option* o = app_.add_option_function<std::string>(
        names,
        [&width, &height, tool, name, lo, hi](const std::string& v) {
            const ImageSize s = parse_size(v, tool, name.c_str(), lo, hi);
            width = s.width;
            height = s.height;
        },
        help);
    o->type_name("WxH, each " + std::to_string(lo) + ".." + std::to_string(hi));
    return o;
}

void CommandLine::reject_second_scene(const std::filesystem::path& scene) const {
    if (!extra_.empty())
        throw core::Error(tool_, "more than one scene given ('" + scene.string() + "', '" + extra_.front() + "')");
}

bool CommandLine::parse(const std::vector<std::string>& args) {
    extra_.clear();
    std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 consumes from the back
    try {
        app_.parse(reversed);
    } catch (const CLI::CallForHelp&) {
        return false;
    } catch (const CLI::ArgumentMismatch& e) {
        reject_unknown_options();
        // Only options with a fixed number of values are declared: the value is missing, and
        // the option is the last argument (as the user spelled it).
        const std::string what = e.what();
        const bool last_is_option = !args.empty() && args.back().size() > 1 && args.back()[0] == '-';
        throw core::Error(tool_, (last_is_option ? args.back() : what.substr(0, what.find(':'))) + " needs a value");
    } catch (const CLI::RequiredError& e) {
        reject_unknown_options();
        // "<option> is required" (its short name when it has one, as users type it); a missing
        // positional reads "no <name> given (see --help)".
        const std::string what = e.what();
        const CLI::Option* o = app_.get_option_no_throw(what.substr(0, what.find(' ')));
        if (o && !o->nonpositional()) throw core::Error(tool_, "no " + o->get_name() + " given (see --help)");
        if (o && !o->get_snames().empty()) throw core::Error(tool_, "-" + o->get_snames().front() + " is required");
        throw core::Error(tool_, what);
    } catch (const CLI::ParseError& e) {
        reject_unknown_options();
        throw core::Error(tool_, e.what());
    } catch (const core::Error&) {  // an option's own check (number(), parse_size(), ...)
        reject_unknown_options();
        throw;
    }
    reject_unknown_options();
    for (const std::string& s : app_.remaining()) extra_.push_back(s);
    return true;
}

CLI::Option* add_choice(CLI::App& app, const std::string& option, std::function<void(const std::string&)> set,
                        std::span<const std::string_view> names, const std::string& help) {
    std::vector<std::string> allowed(names.begin(), names.end());
    std::string list;
    for (std::size_t i = 0; i < allowed.size(); ++i)
        list += (i == 0 ? "" : i + 1 == allowed.size() ? " or " : ", ") + allowed[i];
    return app.add_option_function<std::string>(option, std::move(set), help + ": " + list)
        ->check(CLI::IsMember(std::move(allowed)));
}

}  // namespace fulgur::app
