#include "render/detail/gl_program.h"

#include "core/core.h"

#include <glad/gl.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace fulgur::render::detail {

namespace {

std::string read_file(const std::filesystem::path& p, const std::string& where) {
    std::ifstream in(p, std::ios::binary);
    if (!in) throw core::Error(where, "cannot open shader file " + p.string());
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

struct Expander {
    std::filesystem::path dir;
    Preprocessed out;
    std::set<std::string> seen;

    void expand(const std::string& name, bool top, const std::string& defines, const std::string& included_from) {
        const int id = int(out.files.size());
        out.files.push_back(name);
        seen.insert(name);
        const std::string text = read_file(dir / name, included_from.empty() ? name : included_from);
        std::istringstream lines(text);
        std::string line;
        int n = 0;
        bool version_seen = false;
        static const std::regex include_re(R"(^\s*#\s*include\s+\"([^\"]+)\"\s*$)");
        static const std::regex version_re(R"(^\s*#\s*version\b.*$)");
        if (!top) out.text += "#line " + std::to_string(id * kLineBase + 1) + "\n";
        while (std::getline(lines, line)) {
            ++n;
            if (!line.empty() && line.back() == '\r') line.pop_back();
            std::smatch m;
            if (std::regex_match(line, version_re)) {
                if (!top)
                    throw core::Error(name + ":" + std::to_string(n),
                                      "#version is only allowed in the top-level shader");
                if (version_seen) throw core::Error(name + ":" + std::to_string(n), "second #version");
                version_seen = true;
                out.text += line + "\n" + defines;
                if (!defines.empty() && defines.back() != '\n') out.text += "\n";
                out.text += "#line " + std::to_string(id * kLineBase + n + 1) + "\n";
                continue;
            }
            if (std::regex_match(line, m, include_re)) {
                if (top && !version_seen) throw core::Error(name + ":" + std::to_string(n), "#include before #version");
                const std::string child = m[1].str();
                if (!seen.count(child)) expand(child, false, {}, name + ":" + std::to_string(n));
                out.text += "#line " + std::to_string(id * kLineBase + n + 1) + "\n";
                continue;
            }
            if (top && !version_seen) {  // only blank lines and // comments may precede #version
                const auto pos = line.find_first_not_of(" \t");
                if (pos != std::string::npos && line.compare(pos, 2, "//") != 0)
                    throw core::Error(name + ":" + std::to_string(n), "the first statement must be #version");
            }
            out.text += line + "\n";
        }
        if (top && !version_seen) throw core::Error(name, "no #version line");
    }
};

}  // namespace

Preprocessed preprocess(const std::filesystem::path& dir, const std::string& name, const std::string& defines) {
    Expander e{dir, {}, {}};
    e.expand(name, true, defines, {});
    return e.out;
}

MappedLog map_log(const std::string& log, const std::vector<std::string>& files) {
    // Mesa: "0:12(5): error: ..."; NVIDIA: "0(12) : error ..."; AMD/Intel: "ERROR: 0:12: ...".
    static const std::regex mesa(R"(^(\s*)(\d+):(\d+)\((\d+)\)(.*)$)");
    static const std::regex nvidia(R"(^(\s*)(\d+)\((\d+)\)(.*)$)");
    static const std::regex amd(R"(^(\s*(?:ERROR|WARNING): )(\d+):(\d+):(.*)$)");
    MappedLog out;
    auto locate = [&](long line, std::string& loc) -> bool {
        const long file = line / kLineBase;
        if (file < 0 || std::size_t(file) >= files.size()) return false;
        loc = files[std::size_t(file)] + ":" + std::to_string(line % kLineBase);
        return true;
    };
    std::istringstream in(log);
    std::string line;
    while (std::getline(in, line)) {
        std::smatch m;
        std::string loc, rewritten = line;
        if (std::regex_match(line, m, mesa) && locate(std::stol(m[3].str()), loc))
            rewritten = m[1].str() + loc + "(" + m[4].str() + ")" + m[5].str();
        else if (std::regex_match(line, m, amd) && locate(std::stol(m[3].str()), loc))
            rewritten = m[1].str() + loc + ":" + m[4].str();
        else if (std::regex_match(line, m, nvidia) && locate(std::stol(m[3].str()), loc))
            rewritten = m[1].str() + loc + m[4].str();
        if (!loc.empty() && out.first_location.empty()) out.first_location = loc;
        out.text += rewritten + "\n";
    }
    return out;
}

unsigned build_program(const std::filesystem::path& dir, const std::vector<Stage>& stages, const std::string& defines) {
    std::vector<GLuint> shaders;
    std::string names;
    auto cleanup = [&](GLuint program) {
        for (GLuint s : shaders) glDeleteShader(s);
        if (program) glDeleteProgram(program);
    };
    for (const Stage& st : stages) {
        names += (names.empty() ? "" : "+") + st.file;
        Preprocessed pp;
        try {
            pp = preprocess(dir, st.file, defines);
        } catch (...) {
            cleanup(0);
            throw;
        }
        const GLuint s = glCreateShader(st.type);
        shaders.push_back(s);
        const char* src = pp.text.c_str();
        glShaderSource(s, 1, &src, nullptr);
        glCompileShader(s);
        GLint ok = 0, len = 0;
        glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
        if (!ok) {
            glGetShaderiv(s, GL_INFO_LOG_LENGTH, &len);
            std::string log(std::size_t(std::max(len, 1)), '\0');
            glGetShaderInfoLog(s, len, nullptr, log.data());
            log.resize(std::strlen(log.c_str()));
            const MappedLog ml = map_log(log, pp.files);
            cleanup(0);
            throw core::Error(ml.first_location.empty() ? st.file : ml.first_location,
                              "GLSL compile error in " + st.file + ":\n" + ml.text);
        }
    }
    const GLuint p = glCreateProgram();
    for (GLuint s : shaders) glAttachShader(p, s);
    glLinkProgram(p);
    GLint ok = 0, len = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramiv(p, GL_INFO_LOG_LENGTH, &len);
        std::string log(std::size_t(std::max(len, 1)), '\0');
        glGetProgramInfoLog(p, len, nullptr, log.data());
        log.resize(std::strlen(log.c_str()));
        cleanup(p);
        throw core::Error(names, "GLSL link error:\n" + log);
    }
    for (GLuint s : shaders) {
        glDetachShader(p, s);
        glDeleteShader(s);
    }
    return p;
}

}  // namespace fulgur::render::detail
